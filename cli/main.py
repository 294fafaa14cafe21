"""The ``ppo-cv`` command: one typer app, one module per command group."""

from __future__ import annotations

import typer
from ppo_cv.cli import pair, sfm, synth

app = typer.Typer(
    name="ppo-cv",
    help="Relative pose of two calibrated images by the pose-only (PPO) inequalities.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

for _module in (synth, sfm, pair):
    _module.register(app)


def main() -> None:
    app()
