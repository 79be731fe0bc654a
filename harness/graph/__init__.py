"""The paper's graph-theory model of a tree of rigid bodies, one module per section:
topology (2.1), dynamics (2.2), identification form (2.3)."""
