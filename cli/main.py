"""The ``ppo-cv`` command: one typer app, one module per command group."""

from __future__ import annotations

import signal
import sys

import typer

from ppo_cv.atomic import sigterm_as_interrupt, stop_listening
from ppo_cv.cli import batch, pair, sfm, synth

app = typer.Typer(
    name="ppo-cv",
    help="Relative pose of two calibrated images by the pose-only (PPO) inequalities.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

for _module in (synth, sfm, pair, batch):
    _module.register(app)


def _usage_error(exc: Exception) -> int:
    """Print a command-line parsing error as one line; returns the exit code."""
    ctx = getattr(exc, "ctx", None)
    if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
        typer.echo(ctx.get_help(), err=True)
        return 2
    command = ctx.command_path if ctx is not None else "ppo-cv"
    typer.echo(f"{command}: {exc.format_message()}", err=True)
    return getattr(exc, "exit_code", 2)


def _command(argv: list[str] | None) -> str:
    words = [a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith("-")]
    return f"ppo-cv {words[0]}" if words else "ppo-cv"


def _workers_never_see_ctrl_c() -> None:
    """Start spawned worker processes with SIGINT blocked.

    Ctrl-C at a terminal reaches the whole process group; a worker still starting its
    interpreter would die of it with a traceback. Blocked from their first instruction (the
    mask is inherited through fork and exec), the workers leave the interrupt to this process,
    which stops them and removes unfinished output.
    """
    from multiprocessing import popen_spawn_posix

    launch = popen_spawn_posix.Popen._launch
    if getattr(launch, "blocks_sigint", False):
        return

    def launch_blocking_sigint(self, process_obj):
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            return launch(self, process_obj)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)

    launch_blocking_sigint.blocks_sigint = True
    popen_spawn_posix.Popen._launch = launch_blocking_sigint


def main(argv: list[str] | None = None) -> None:
    """Run the command line; a usage error is one line on stderr and exit code 2.

    SIGTERM is handled as Ctrl-C: outputs in progress are removed, exit code 130.
    """
    sigterm_as_interrupt()
    _workers_never_see_ctrl_c()
    try:
        code = app(args=argv, prog_name="ppo-cv", standalone_mode=False)
    except (typer.Abort, KeyboardInterrupt):
        code = 130
    except Exception as exc:  # click's exceptions (typer vendors click in recent releases)
        if not hasattr(exc, "format_message"):
            raise
        code = _usage_error(exc)
    if code == 130:  # typer turns a KeyboardInterrupt into exit code 130, silently
        stop_listening()
        typer.echo(f"{_command(argv)}: interrupted; unfinished output removed", err=True)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
