"""``python -m hertzchain.cli ...``: the same as the ``hertzchain`` command."""

from .main import entry

entry()
