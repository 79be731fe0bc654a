"""The field's identification tools wrapped as identification methods (harness/base/plugins.py): each is
an entry point of group `harness.identification`, installed with its optional extra, and plugs in
through the same door as a user's method. No core module imports them."""
