"""Thin typer shells, one module per stage; each exposes ``register(app)``."""
