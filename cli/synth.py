"""``ppo-cv synth``: render synthetic image pairs with exact ground truth."""

from __future__ import annotations

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def synth() -> None:
        """Render synthetic pairs (not implemented yet)."""
        raise typer.Exit(2)
