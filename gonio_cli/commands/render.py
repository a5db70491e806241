"""Placeholder for the ``gonio render`` shell (being written); registers nothing."""

EXAMPLE = ""


def register(app) -> None:
    pass
