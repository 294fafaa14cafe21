"""Signals at random times to the process group of a running ``ppo-cv`` command.

Run ``python benchmarks/signals.py [--runs 30] [--seed 0] [--signal TERM]``: each run starts a
command (in turn ``pairs --workers 2 -o``, ``pair --out``, ``sfm``, ``synth --workers 2``) on
the built-in demo pair in a fresh folder and its own process group, sends the signal to the
whole group (as ``timeout``, a service manager or Ctrl-C at a terminal do) after a delay drawn
uniformly in [0, 3] s, and waits 10 s. Prints, per command, the exit codes seen and how many
runs hung (a process of the group still alive after 10 s), printed more than one line on
stderr, printed a traceback or a native stack dump, or left anything in the folder beside the
inputs without succeeding (a signal that comes once the work is done is ignored: exit code 0
and the whole output). SIGKILL (``--signal KILL``) checks only what is left behind.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import platform
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cli_time import installed_command

DATA = Path(__file__).resolve().parents[1] / "ppo_cv" / "data"
DEMO = json.loads((DATA / "demo.json").read_text())
K_TEXT = ",".join(str(v) for v in DEMO["intrinsics"])
GRACE_SECONDS = 10.0
DELAY_SECONDS = 3.0


def _inputs(folder: Path) -> None:
    images = folder / "images"
    images.mkdir()
    for name in (DEMO["image1"], DEMO["image2"]):
        shutil.copy(DATA / name, images / name)
    lines = [f"{DEMO['image1']} {DEMO['image2']}", f"{DEMO['image2']} {DEMO['image1']}"] * 3
    (folder / "six.txt").write_text("\n".join(lines) + "\n")


COMMANDS = {
    "pairs": ["pairs", "-q", "--workers", "2", "six.txt", "images", "--K", K_TEXT, "-o", "h.jsonl"],
    "pair": ["pair", f"images/{DEMO['image1']}", f"images/{DEMO['image2']}", "--K", K_TEXT,
             "--out", "result"],
    "sfm": ["sfm", "images", "model", "--K", K_TEXT, "--threads", "1", "-q"],
    "synth": ["synth", "render", "--pairs", "6", "--workers", "2", "--width", "160",
              "--height", "120", "-q"],
}  # fmt: skip


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _default_sigint() -> None:
    """As at a terminal: a shell's background job would pass SIGINT on ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _one_run(name: str, signum: int, delay: float) -> dict:
    with tempfile.TemporaryDirectory(prefix="ppo-cv-signals-") as scratch:
        folder = Path(scratch)
        _inputs(folder)
        before = {p.relative_to(folder) for p in folder.rglob("*")}
        process = subprocess.Popen(
            [*installed_command(), *COMMANDS[name]], cwd=folder, start_new_session=True,
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            text=True, preexec_fn=_default_sigint,
        )  # fmt: skip
        time.sleep(delay)
        finished_first = process.poll() is not None
        if not finished_first:
            os.killpg(process.pid, signum)
        hung = False
        try:
            _, err = process.communicate(timeout=GRACE_SECONDS)
        except subprocess.TimeoutExpired:
            hung = True
        deadline = time.monotonic() + (0 if hung else GRACE_SECONDS)
        while _group_alive(process.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        hung = hung or _group_alive(process.pid)
        if hung:
            os.killpg(process.pid, signal.SIGKILL)
            _, err = process.communicate()
        after = {p.relative_to(folder) for p in folder.rglob("*")}
        lines = err.strip().splitlines()
        return {
            "finished first": finished_first,
            "code": process.returncode,
            "hung": hung,
            "lines": len(lines),
            "traceback": any("Traceback" in line or "*** SIG" in line for line in lines),
            "left": sorted(str(p) for p in after - before) if process.returncode else [],
            "stderr": lines,
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--signal", default="TERM", choices=["TERM", "INT", "KILL"])
    args = parser.parse_args()
    signum = getattr(signal, f"SIG{args.signal}")
    draw = random.Random(args.seed)
    names = list(COMMANDS)
    rows = collections.defaultdict(list)
    for number in range(args.runs):
        name = names[number % len(names)]
        delay = draw.uniform(0.0, DELAY_SECONDS)
        outcome = _one_run(name, signum, delay)
        rows[name].append(outcome)
        odd = outcome["hung"] or outcome["traceback"] or outcome["left"] or (
            outcome["lines"] > 1 and signum != signal.SIGKILL and not outcome["finished first"]
        )
        if odd:
            print(f"run {number} {name} after {delay:.2f} s: {outcome}", file=sys.stderr)
    print(f"SIG{args.signal} to the process group after U(0, {DELAY_SECONDS:g}) s, "
          f"{args.runs} runs, seed {args.seed}; {platform.platform()}, {os.cpu_count()} CPUs, "
          f"Python {platform.python_version()}\n")  # fmt: skip
    print("| command | runs | done before the signal | exit codes | hung after 10 s | "
          "stderr > 1 line | traceback or stack dump | left behind |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for name, outcomes in rows.items():
        signalled = [o for o in outcomes if not o["finished first"]]
        codes = collections.Counter(o["code"] for o in signalled)
        print(
            f"| {name} | {len(outcomes)} | {len(outcomes) - len(signalled)} | "
            + ", ".join(f"{code}: {count}" for code, count in sorted(codes.items()))
            + f" | {sum(o['hung'] for o in outcomes)} | "
            f"{sum(o['lines'] > 1 for o in signalled)} | "
            f"{sum(o['traceback'] for o in outcomes)} | {sum(bool(o['left']) for o in outcomes)} |"
        )


if __name__ == "__main__":
    main()
