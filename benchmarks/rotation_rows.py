"""The stored rows of ``pure_rotation.py``: which sets count, and the flags counted over them.

Shared by ``pure_rotation.py``'s report and ``compare_report.py``'s summary of it, so that both
count the same pairs.
"""

from __future__ import annotations

__all__ = ["main_set", "evaluated", "flag_counts"]


def main_set(name: str, data: dict) -> bool:
    """A set of the main table: not the sweep, not run with a setting other than the default
    (``name`` a key of the rows file, ``data`` its ``{"label", "rows", ...}``)."""
    return not name.startswith(("_", "sweep")) and "focal_ratio" not in data


def evaluated(rows: list[dict]) -> list[dict]:
    """The rows of the pairs on which ppo_cv returned a pose."""
    return [r for r in rows if "error" not in r]


def flag_counts(results: dict, key: str) -> tuple[int, int, int]:
    """``(true flags, flags, pure rotations)`` of the flag ``key`` over the main sets' pairs
    that have it; precision is the first over the second, recall the first over the third."""
    true = flagged = positives = 0
    for name, data in results.items():
        if not main_set(name, data):
            continue
        for row in data["rows"]:
            if key in row:
                true += bool(row[key]) and bool(data["label"])
                flagged += bool(row[key])
                positives += bool(data["label"])
    return true, flagged, positives


if __name__ == "__main__":
    raise SystemExit(
        "rotation_rows.py is a module of pure_rotation.py and compare_report.py, not a script; run "
        "python benchmarks/pure_rotation.py --help"
    )
