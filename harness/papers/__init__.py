"""The seed papers, each a package that plugs into the harness through harness/base/plugins.py exactly
as a user's code does. Nothing in the core imports them."""
