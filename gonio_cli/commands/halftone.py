"""Placeholder for the ``gonio halftone`` shell (being written); registers nothing."""

EXAMPLE = ""


def register(app) -> None:
    pass
