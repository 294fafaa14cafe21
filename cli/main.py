"""The ``ppo-cv`` command: one typer app, one module per command group.

Only the standard library and :mod:`ppo_cv.atomic` are imported with this module: :func:`main`
sets the signal handlers before typer, numpy, OpenCV and pycolmap load, so that an interrupt
in the start-up is one line too.
"""

from __future__ import annotations

import errno
import functools
import itertools
import os
import re
import sys

from ppo_cv.atomic import (
    import_pycolmap,
    interrupt_exit_code,
    sigterm_as_interrupt,
    stop_listening,
)

__all__ = ["BLAS_THREAD_VARIABLES", "OPENMP_THREAD_VARIABLES", "main"]

_PYCOLMAP_COMMANDS = {"pair", "demo", "pairs", "sfm"}
"""Commands that import pycolmap: it is imported first, with the signals held back."""

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""Set to 1 by :func:`main` before numpy loads, unless the user set them: the linear algebra of
a pair is on small matrices, where BLAS threads only wait for each other and contend with the
detector's threads and the other workers (``ppo-cv pairs`` on freiburg, 2 workers: 20 % less
CPU and wall time, docs/performance.md)."""

_COUNT = r"[ \t]*\+?0*[1-9][0-9]{0,17}[ \t]*"
OPENMP_THREAD_VARIABLES = {
    "OMP_NUM_THREADS": re.compile(rf"{_COUNT}(?:,{_COUNT})*"),
    "OMP_THREAD_LIMIT": re.compile(_COUNT),
}
"""Thread counts the OpenMP runtime of pycolmap and OpenCV reads when it loads, and the values
it accepts (positive whole numbers; a comma-separated list of them for nested levels). A value
it cannot read ("abc", "0", "") it ignores with two lines of its own on stderr; :func:`main`
drops such a value before, with one warning line."""


@functools.cache
def _app():
    import typer

    from ppo_cv.cli import batch, pair, sfm, synth
    from ppo_cv.cli.common import PanelledHelpCommand, WrappedHelpGroup

    application = typer.Typer(
        name="ppo-cv",
        help="Relative pose of two calibrated images by the pose-only (PPO) inequalities.",
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        rich_markup_mode=None,
        cls=WrappedHelpGroup,
    )

    @application.callback()
    def root(
        version: bool = typer.Option(
            False, "--version", is_eager=True, callback=_print_version,
            help="Print the version and exit.",
        ),
    ) -> None:
        """Relative pose of two calibrated images by the pose-only (PPO) inequalities."""

    for module in (synth, sfm, pair, batch):
        module.register(application)
    for command in application.registered_commands:
        command.cls = PanelledHelpCommand
    return application


def _print_version(value: bool) -> None:
    import typer

    if value:
        from ppo_cv import __version__

        typer.echo(f"ppo-cv {__version__}")
        raise typer.Exit()


def __getattr__(name: str):
    if name == "app":  # the typer app, built on first use
        return _app()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _usage_error(exc: Exception, argv: list[str] | None) -> int:
    """Print a command-line parsing error as one line; returns the exit code."""
    import typer

    ctx = getattr(exc, "ctx", None)
    if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
        typer.echo(ctx.get_help(), err=True)
        return 2
    command = ctx.command_path if ctx is not None else _command(argv)
    from .common import short_words

    message = short_words(exc.format_message(), 80)
    args = sys.argv[1:] if argv is None else argv
    if message.startswith("Got unexpected extra argument"):
        message += _spread_numbers_hint(args) or _loose_numbers_hint(args)
    if message.startswith("No such command") and ctx is not None:
        hint = _command_first_hint(args, ctx.command.list_commands(ctx))
        message = message.rstrip(".") + hint if hint else message
    typer.echo(f"{command}: {message}", err=True)
    return getattr(exc, "exit_code", 2)


_NUMBER_LIST_OPTIONS = ("--K", "--K2", "--dist", "--dist2")
"""Options that take several numbers as one argument (``--K 535.4,539.2,320.1,247.6``)."""


def _spread_numbers_hint(args: list[str]) -> str:
    """The remedy when an option of :data:`_NUMBER_LIST_OPTIONS` was given its numbers as
    separate arguments (``--K 535.4 539.2 320.1 247.6``), the rest of which the command line
    then reads as extra arguments; empty otherwise."""

    def number(text: str) -> bool:
        try:
            float(text)
        except ValueError:
            return False
        return True

    for position, option in enumerate(args):
        values = list(itertools.takewhile(number, args[position + 1 :]))
        if option in _NUMBER_LIST_OPTIONS and len(values) > 1:
            return (
                f"; {option} takes its numbers as one argument, joined by commas: "
                f"{option} {','.join(values)}"
            )
    return ""


def _loose_numbers_hint(args: list[str]) -> str:
    """The remedy when intrinsics were given without their option (``ppo-cv pair a.png b.png
    535.4,539.2,320.1,247.6``); empty otherwise."""
    for position, text in enumerate(args):
        previous = args[position - 1] if position else ""
        numbers = [p for p in re.split(r"[,\s;\[\]()]+", text) if p]
        if previous.startswith("-") or len(numbers) not in (4, 9):
            continue
        if all(re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", n) for n in numbers):
            return f"; intrinsics go after --K: --K {','.join(numbers)}"
    return ""


def _command_first_hint(args: list[str], commands: list[str]) -> str:
    """The remedy when the command's name follows its arguments (``ppo-cv a.png b.png pair``);
    empty when no argument names a command."""
    named = next((a for a in args[1:] if a in commands), None)
    if named is None:
        return ""
    return f"; the command comes first: ppo-cv {named} followed by its arguments"


def _command(argv: list[str] | None) -> str:
    words = [a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith("-")]
    return f"ppo-cv {words[0]}" if words else "ppo-cv"


def _stdout_error() -> OSError | None:
    """The error of writing what standard output still holds (a full disk, ``/dev/full``)."""
    try:
        sys.stdout.flush()
    except OSError as exc:
        return exc
    return None


def _drop_stdout() -> None:
    """Point standard output at the null device, so that the interpreter's exit, flushing what
    is left in it, does not fail with a traceback."""
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, sys.stdout.fileno())
    finally:
        os.close(null)


def _null_for_closed_stderr() -> None:
    """Started with ``2>&-``: the null device as standard error. Else messages have nowhere to
    go, and the next file opened takes descriptor 2, where native libraries write theirs."""
    if sys.stderr is not None:
        return
    null = os.open(os.devnull, os.O_WRONLY)
    if null != 2:
        os.dup2(null, 2)
        os.close(null)
    sys.stderr = open(2, "w", closefd=False)  # noqa: SIM115 - the process's stderr


def _drop_unreadable_thread_counts(argv: list[str] | None) -> None:
    """Remove an :data:`OPENMP_THREAD_VARIABLES` value the OpenMP runtime cannot read, with a
    warning; the runtime would ignore it too, after two lines of its own on stderr."""
    for variable, accepted in OPENMP_THREAD_VARIABLES.items():
        value = os.environ.get(variable)
        if value is not None and not accepted.fullmatch(value):
            del os.environ[variable]
            print(f"{_command(argv)}: warning: {variable}={value!r} is not a positive whole "
                  "number; ignored", file=sys.stderr)  # fmt: skip


_PIXEL_LIMIT_VARIABLE = "PPO_CV_MAX_IMAGE_PIXELS"
""":data:`ppo_cv.images.MAX_PIXELS_ENV`, named here before numpy loads."""


def _drop_empty_pixel_limit(argv: list[str] | None) -> None:
    """Remove an empty ``PPO_CV_MAX_IMAGE_PIXELS``, with a warning, as an unreadable OpenMP
    thread count is removed: set to nothing, it is unset (the default limit)."""
    value = os.environ.get(_PIXEL_LIMIT_VARIABLE)
    if value is not None and not value.strip():
        del os.environ[_PIXEL_LIMIT_VARIABLE]
        print(f"{_command(argv)}: warning: {_PIXEL_LIMIT_VARIABLE}={value!r} is empty; "
              "ignored", file=sys.stderr)  # fmt: skip


def _run(argv: list[str] | None) -> int:
    """The command's exit code; 130 when it was interrupted."""
    if _command(argv).split()[-1] in _PYCOLMAP_COMMANDS:
        import_pycolmap()  # first: numpy's threads, started by it, then block SIGTERM too
    application = _app()
    from ppo_cv.cli.common import ignore_library_camera_warnings

    ignore_library_camera_warnings()
    try:
        return application(args=argv, prog_name="ppo-cv", standalone_mode=False)
    except SystemExit as exc:  # click's exit on a broken pipe, silent and with code 1
        broken = exc.__context__
        if not (isinstance(broken, OSError) and broken.errno == errno.EPIPE):
            raise
        from ppo_cv.cli.common import stdout_failure

        _drop_stdout()
        print(f"{_command(argv)}: {stdout_failure(broken)}", file=sys.stderr)
        return 2
    except Exception as exc:  # click's exceptions (typer vendors click in recent releases)
        if type(exc).__name__ == "Abort":  # click's form of a KeyboardInterrupt
            return 130
        if not hasattr(exc, "format_message"):
            raise
        return _usage_error(exc, argv)


def main(argv: list[str] | None = None) -> None:
    """Run the command line; a usage error is one line on stderr and exit code 2.

    SIGINT and SIGTERM stop the run: outputs in progress are removed, one line on stderr,
    exit code 130 (SIGINT) or 143 (SIGTERM).
    """
    _null_for_closed_stderr()
    for variable in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(variable, "1")
    _drop_unreadable_thread_counts(argv)
    _drop_empty_pixel_limit(argv)
    sigterm_as_interrupt()
    if sys.stdout is None:  # started with ">&-": every command prints its result there
        print(f"{_command(argv)}: standard output is closed; redirect it to a file or "
              f"{os.devnull}", file=sys.stderr)  # fmt: skip
        sys.exit(2)
    try:
        code = _run(argv)
    except KeyboardInterrupt:
        code = 130
    failure = _stdout_error()
    if failure is not None:
        _drop_stdout()
        if code == 0:
            from ppo_cv.cli.common import stdout_failure

            print(f"{_command(argv)}: {stdout_failure(failure)}", file=sys.stderr)
            code = 2
    if code == 130:  # typer turns a KeyboardInterrupt into exit code 130, silently
        stop_listening()
        code = interrupt_exit_code()
        print(f"{_command(argv)}: interrupted; unfinished output removed", file=sys.stderr)
    elif argv is None:  # the work is done: a late signal must not kill the interpreter's exit
        stop_listening()
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
