"""The redundant planar manipulator paper (Yahya et al. 2012): a 6-joint planar arm in two designs,
one motor per joint against one motor driving joints 3..6 through gears. Its study
(`study.STUDY`, asked for by `[studies.yahya2012]`) checks the paper's design claims against the
conventional design on the same path, and audits the printed closed-form inertia matrix against
Pinocchio's CRBA. It plugs in through harness/base/plugins.py like any user's study."""
