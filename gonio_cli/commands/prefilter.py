"""Placeholder for the ``gonio prefilter`` shell (being written); registers nothing."""

EXAMPLE = ""


def register(app) -> None:
    pass
