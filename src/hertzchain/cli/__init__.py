"""The command line ``hertzchain``: :mod:`~hertzchain.cli.main` (the group, the error path, the
console script), one module per subcommand, and :mod:`~hertzchain.cli.common` (what they share).

Nothing is imported here: ``from hertzchain.cli.main import main`` runs the command line in a
process (``main(["run", "config.toml", "--out", "result.nc"])`` returns the exit status).
"""
