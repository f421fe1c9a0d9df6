"""``python -m hertzchain.cli ...``: the same as the ``hertzchain`` command."""

from .main import entry

if __name__ == "__main__":  # not when a tool imports every module (Sphinx walks the package)
    entry()
