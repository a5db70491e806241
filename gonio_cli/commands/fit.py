"""Placeholder: replaced by the fit stage's shell."""


def register(app) -> None:
    pass
