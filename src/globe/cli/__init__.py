"""The ``globe`` command line (typer + rich)."""
