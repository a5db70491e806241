"""Placeholder for the ``gonio lobes`` shell (being written); registers nothing."""

EXAMPLE = ""


def register(app) -> None:
    pass
