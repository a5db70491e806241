"""Placeholder: replaced by the ingest stage's shell."""


def register(app) -> None:
    pass
