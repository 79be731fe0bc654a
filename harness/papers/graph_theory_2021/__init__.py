"""The graph-theory paper (Appl. Sci. 2021, 11(22), 10988): a tree of rigid bodies described by its
incidence matrix, Newton-Euler equations in Cardano coordinates, constraints and Lagrange
multipliers, and a least-squares identification of each body's mass and principal inertias.

It plugs into the harness through the doors any user's code uses (harness/base/plugins.py):
- `model.make`: the graph model as a model under test (entry point `harness.models:graph_theory_2021`);
- `study.STUDY`: its stages, asked for by `[studies.graph_theory_2021]` in a scenario.

One module per section: topology (2.1), dynamics (2.2), identification form (2.3), constraints
(2.4), constrained dynamics (2.5), forward simulation; inverse dynamics from the same equations.
"""
