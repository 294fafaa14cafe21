"""Tables, plots and the markdown report of the side-by-side benchmark (``compare.py``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from anchors import auc
from rotation_rows import evaluated, flag_counts, main_set

__all__ = ["summarise", "draw", "render", "headline", "pure_rotation_lines"]

THRESHOLDS = (5, 10, 20)
PURE_ROTATION_ROWS = Path(__file__).resolve().parent / "pure_rotation.json"
"""Rows of ``pure_rotation.py``'s last full run, summarised in section 3."""
PURE_ROTATION_GROUPS = {
    "exact rotations (t = 0)": lambda name, label: label == 1 and "tripod" not in name,
    "tripod pans (pivot 8-15 cm)": lambda name, label: "tripod" in name,
    "translating renders, baseline / depth >= 0.02": (
        lambda name, label: label == 0 and name != "freiburg"
    ),
    "freiburg (real, translating)": lambda name, label: name == "freiburg",
}
PURE_ROTATION_METHODS = {
    "ppo_cv_R_err": "ppo_cv",
    "pycolmap_R_err": "pycolmap",
    "opencv_R_err": "OpenCV",
    "poselib_R_err": "PoseLib",
}
LABELS = {
    "ppo_cv": "ppo_cv estimate_pair",
    "opencv": "OpenCV",
    "opencv + ppo_cv": "OpenCV E + ppo_cv.recoverPose",
    "pycolmap": "pycolmap two-view geometry",
    "pycolmap relpose": "pycolmap relpose + refine",
    "poselib": "PoseLib",
}
DETECTION_MOTIONS = ("pure-rotation", "small-parallax", "planar", "general")
OUR_DETECTOR = "ppo_cv estimate_pair: PRI < 0.015"
DROP_IN_DETECTOR = "OpenCV E + ppo_cv: PRI < 0.015"
FILES = {
    "speed": "identification_speed.png",
    "auc": "accuracy_auc.png",
    "detection": "pure_rotation_detection.png",
    "pipeline": "pipeline_time.png",
    "memory": "memory_per_point.png",
}


def _sets(pairs: list[dict]) -> dict[str, list[dict]]:
    sets: dict[str, list[dict]] = {}
    for row in pairs:
        key = f"rendered {row['motion']}" if row["set"] == "rendered" else "freiburg"
        sets.setdefault(key, []).append(row)
    rendered = [r for r in pairs if r["set"] == "rendered"]
    if rendered:
        sets["rendered, all presets"] = rendered
    return sets


def _detectors(rows: list[dict], m3_threshold: float) -> dict[str, np.ndarray]:
    ppo = [r["methods"]["ppo_cv"] for r in rows]
    drop_in = [r["methods"]["opencv + ppo_cv"] for r in rows]
    config = [r["methods"]["pycolmap"].get("config") for r in rows]
    m3 = np.array([p.get("m3", np.nan) for p in ppo], dtype=float)
    return {
        OUR_DETECTOR: np.array([bool(p.get("pure_rotation")) for p in ppo]),
        DROP_IN_DETECTOR: np.array([bool(p.get("pure_rotation")) for p in drop_in]),
        "pycolmap: PANORAMIC": np.array([c == "PANORAMIC" for c in config]),
        "pycolmap: PANORAMIC or PLANAR_OR_PANORAMIC": np.array(
            [c in ("PANORAMIC", "PLANAR_OR_PANORAMIC") for c in config]
        ),
        f"M3 < {m3_threshold:g} (estimate_pair's pose and inliers)": np.nan_to_num(m3, nan=np.inf)
        < m3_threshold,
        "_m3": m3,
    }


def _best_threshold(scores: np.ndarray, positive: np.ndarray) -> float:
    finite = np.isfinite(scores)
    candidates = np.unique(scores[finite])
    best, best_j = float("nan"), -np.inf
    for c in candidates:
        flagged = scores <= c
        tpr = flagged[positive].mean() if positive.any() else 0.0
        fpr = flagged[~positive].mean() if (~positive).any() else 0.0
        if tpr - fpr > best_j:
            best, best_j = float(c), tpr - fpr
    return best


def summarise(res: dict) -> dict:
    """Every table of the report as plain numbers."""
    s: dict = {"settings": res["settings"]}
    ident = []
    for row in res["identification"]:
        ident.append(
            {
                **row,
                "cv2_ratio": row["cv2.recoverPose"] / row["ppo_cv.recoverPose"],
                "pycolmap_ratio": row["pycolmap pose from E"] / row["ppo_cv.recoverPose"],
            }
        )
    s["identification"] = ident

    accuracy = {}
    for name, rows in _sets(res["pairs"]).items():
        entry = {"pairs": len(rows)}
        for method in LABELS:
            errors = [r["methods"][method]["err"] for r in rows]
            failed = sum(bool(r["methods"][method].get("failed")) for r in rows)
            entry[method] = {
                "auc": [100 * auc(errors, th) for th in THRESHOLDS],
                "failed": failed,
                "median_err": float(np.median(errors)),
            }
        accuracy[name] = entry
    s["accuracy"] = accuracy

    rows = [r for r in res["pairs"] if r["set"] == "rendered" and r["motion"] in DETECTION_MOTIONS]
    positive = np.array([r["motion"] == "pure-rotation" for r in rows])
    m3_threshold = res["settings"]["m3_threshold"]
    dets = _detectors(rows, m3_threshold)
    m3 = dets.pop("_m3")
    oracle = _best_threshold(m3, positive)
    dets[f"M3 <= {oracle:.2g} (best threshold on these pairs)"] = (
        np.nan_to_num(m3, nan=np.inf) <= oracle
    )
    motions = np.array([r["motion"] for r in rows])
    detection = {}
    for name, flagged in dets.items():
        tp = int(np.sum(flagged & positive))
        fp = int(np.sum(flagged & ~positive))
        fn = int(np.sum(~flagged & positive))
        detection[name] = {
            "precision": tp / (tp + fp) if tp + fp else float("nan"),
            "recall": tp / (tp + fn) if tp + fn else float("nan"),
            "rates": {
                m: float(np.mean(flagged[motions == m]))
                for m in DETECTION_MOTIONS
                if np.any(motions == m)
            },
        }
    s["detection"] = detection
    s["detection_counts"] = {m: int(np.sum(motions == m)) for m in DETECTION_MOTIONS}
    ppo_failed = {
        m: int(sum(bool(r["methods"]["ppo_cv"].get("failed")) for r in rows if r["motion"] == m))
        for m in DETECTION_MOTIONS
    }
    s["detection_ppo_failed"] = ppo_failed

    s["pipeline"] = res["pipeline_speed"]
    s["memory"] = res["memory"]
    s["losses"] = _losses(s)
    s["wins"] = _wins(s)
    return s


def _wins(s: dict) -> list[str]:
    """Every row where ppo_cv is ahead of all anchors, in words."""
    out = []
    for row in s["identification"]:
        if row["cv2_ratio"] > 1 and row["pycolmap_ratio"] > 1:
            out.append(
                f"identification at N = {row['n']}: {row['cv2_ratio']:.1f}x faster than "
                f"`cv2.recoverPose`, {row['pycolmap_ratio']:.1f}x faster than pycolmap"
            )
    anchors_ = ("opencv", "pycolmap", "pycolmap relpose", "poselib")
    for name, entry in s["accuracy"].items():
        ours = entry["ppo_cv"]["auc"]
        best = [max(entry[m]["auc"][k] for m in anchors_) for k in range(len(THRESHOLDS))]
        if all(o >= b for o, b in zip(ours, best, strict=True)):
            out.append(
                f"accuracy on {name}: `estimate_pair` has the best AUC@5/10/20 "
                f"({_auc_cell(entry['ppo_cv'])}; best anchor "
                + " / ".join(f"{b:.1f}" for b in best)
                + ")"
            )
        drop, cv = entry["opencv + ppo_cv"]["auc"], entry["opencv"]["auc"]
        if drop[1] > cv[1] + 0.05:
            out.append(
                f"accuracy on {name}: replacing only `cv2.recoverPose` by "
                f"`ppo_cv.recoverPose` in the OpenCV pipeline raises AUC@5/10/20 from "
                f"{_auc_cell(entry['opencv'])} to {_auc_cell(entry['opencv + ppo_cv'])}"
            )
    pipe = s["pipeline"]
    ours_t = pipe.get("ppo_cv estimate_pair")
    others = [pipe[k] for k in ("OpenCV pipeline", "pycolmap pipeline") if k in pipe]
    if ours_t is not None and others and ours_t < min(others):
        out.append(
            f"whole-pair time: `estimate_pair` {ours_t:.2f} s per pair"
            f"{_cpu_note(pipe, 'ppo_cv estimate_pair')}, the OpenCV and pycolmap pipelines "
            + " and ".join(
                f"{pipe[k]:.2f} s{_cpu_note(pipe, k)}"
                for k in ("OpenCV pipeline", "pycolmap pipeline")
                if k in pipe
            )
        )
    mem = {(r["method"], r["n"]): r for r in s["memory"]}
    n = max(r["n"] for r in s["memory"])
    ours_m, cv_m = mem.get(("ppo_cv.recoverPose", n)), mem.get(("cv2.recoverPose", n))
    if ours_m and cv_m and ours_m["rss_bytes"] and cv_m["rss_bytes"]:
        out.append(
            f"peak memory at N = {n:,}: `ppo_cv.recoverPose` "
            f"{ours_m['rss_bytes'] / n:.0f} bytes per point, `cv2.recoverPose` "
            f"{cv_m['rss_bytes'] / n:.0f}"
        )
    return out


def _losses(s: dict) -> list[str]:
    """Every row where ppo_cv is behind an anchor, in words."""
    out = []
    for row in s["identification"]:
        if row["cv2_ratio"] < 1:
            out.append(
                f"identification at N = {row['n']}: `cv2.recoverPose` is "
                f"{1 / row['cv2_ratio']:.1f}x faster than `ppo_cv.recoverPose`"
            )
        if row["pycolmap_ratio"] < 1:
            out.append(
                f"identification at N = {row['n']}: pycolmap's pose from E is "
                f"{1 / row['pycolmap_ratio']:.1f}x faster than `ppo_cv.recoverPose`"
            )
    for name, entry in s["accuracy"].items():
        ours = entry["ppo_cv"]["auc"]
        for method in ("opencv", "pycolmap", "pycolmap relpose", "poselib"):
            theirs = entry[method]["auc"]
            behind = [
                f"@{th}: {o:.1f} vs {t:.1f}"
                for th, o, t in zip(THRESHOLDS, ours, theirs, strict=True)
                if o < t - 0.05
            ]
            if behind:
                out.append(
                    f"accuracy on {name}: {LABELS[method]} is ahead of ppo_cv "
                    f"estimate_pair (AUC {', '.join(behind)})"
                )
    det = s["detection"]
    ours = det.get(OUR_DETECTOR)
    if ours:
        for name, d in det.items():
            if name in (OUR_DETECTOR, DROP_IN_DETECTOR):
                continue
            if _f1(d) > _f1(ours) + 1e-9:
                out.append(
                    f"pure-rotation detection: {name} has a higher F1 "
                    f"({_f1(d):.2f}) than ppo_cv's flag ({_f1(ours):.2f})"
                )
    pipe = s["pipeline"]
    ours_t = pipe.get("ppo_cv estimate_pair")
    for label in ("OpenCV pipeline", "pycolmap pipeline"):
        if ours_t is not None and label in pipe and pipe[label] < ours_t:
            out.append(
                f"whole-pair time: the {label} takes {pipe[label]:.2f} s per pair"
                f"{_cpu_note(pipe, label)}, `estimate_pair` {ours_t:.2f} s"
                f"{_cpu_note(pipe, 'ppo_cv estimate_pair')}"
            )
    return out


def _cpu_note(pipe: dict, label: str) -> str:
    """`` (CPU x s)`` when the run measured CPU time too."""
    cpu = pipe.get("cpu", {}).get(label)
    return "" if cpu is None else f" (CPU {cpu:.2f} s)"


def _f1(d: dict) -> float:
    p, r = d["precision"], d["recall"]
    if not (np.isfinite(p) and np.isfinite(r)) or p + r == 0:
        return 0.0
    return 2 * p * r / (p + r)


def draw(res: dict, s: dict, out: Path, figures: tuple[str, ...] | None = None) -> None:
    """The figures of :data:`FILES` (only the keys in ``figures`` when given) into ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if figures is not None:
        if "pipeline" in figures:
            _draw_pipeline(plt, s, out)
        return
    sizes = [r["n"] for r in s["identification"]]
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for name in ("ppo_cv.recoverPose", "cv2.recoverPose", "pycolmap pose from E"):
        ax.loglog(sizes, [r[name] * 1e3 for r in s["identification"]], marker="o", label=name)
    ax.set_xlabel("number of points N")
    ax.set_ylabel("median time per call (ms)")
    ax.set_title("Pose identification from the same E and points", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / FILES["speed"], dpi=110)
    plt.close(fig)

    names = list(s["accuracy"])
    methods = list(LABELS)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), sharey=True)
    width = 0.8 / len(methods)
    for k, th in enumerate(THRESHOLDS):
        ax = axes[k]
        for j, method in enumerate(methods):
            values = [s["accuracy"][n][method]["auc"][k] for n in names]
            ax.bar(
                np.arange(len(names)) + (j - len(methods) / 2 + 0.5) * width,
                values,
                width,
                label=LABELS[method],
            )
        ax.set_xticks(np.arange(len(names)))
        ax.set_xticklabels(
            [n.replace("rendered ", "") for n in names], rotation=35, ha="right", fontsize=8
        )
        ax.set_title(f"AUC@{th} deg", fontsize=10)
    axes[0].set_ylabel("AUC (%)")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / FILES["auc"], dpi=110)
    plt.close(fig)

    det = s["detection"]
    fig, ax = plt.subplots(figsize=(10, 4.2))
    width = 0.8 / len(det)
    for j, (name, d) in enumerate(det.items()):
        values = [d["rates"].get(m, np.nan) * 100 for m in DETECTION_MOTIONS]
        ax.bar(
            np.arange(len(DETECTION_MOTIONS)) + (j - len(det) / 2 + 0.5) * width,
            values,
            width,
            label=name,
        )
    ax.set_xticks(np.arange(len(DETECTION_MOTIONS)))
    ax.set_xticklabels(DETECTION_MOTIONS)
    ax.set_ylabel("pairs flagged as pure rotation (%)")
    ax.set_title(
        "Pure-rotation flags per motion preset (only pure-rotation should be flagged)", fontsize=10
    )
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / FILES["detection"], dpi=110)
    plt.close(fig)

    _draw_pipeline(plt, s, out)

    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for method in sorted({r["method"] for r in s["memory"]}):
        rows = [r for r in s["memory"] if r["method"] == method]
        ax.semilogx(
            [r["n"] for r in rows],
            [
                (r["rss_bytes"] if r["rss_bytes"] is not None else r["traced_bytes"]) / r["n"]
                for r in rows
            ],
            marker="o",
            label=method,
        )
    ax.set_xlabel("number of points N")
    ax.set_ylabel("peak bytes per point (RSS rise)")
    ax.set_ylim(bottom=0)
    ax.set_title("Peak memory of one identification call", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / FILES["memory"], dpi=110)
    plt.close(fig)


def _pipeline_rows(pipe: dict) -> list[tuple[str, float, float]]:
    """(pipeline, median wall s, median CPU s or nan) per timed pipeline, the baseline first."""
    cpu = pipe.get("cpu", {})
    rows = []
    base = pipe.get("baseline")
    if base is not None:
        ours = "ppo_cv estimate_pair"
        rows.append((f"{ours}, {base['label']}", base[ours], base["cpu"][ours]))
    for key, value in pipe.items():
        if isinstance(value, float):
            rows.append((key, value, cpu.get(key, float("nan"))))
    return rows


def _draw_pipeline(plt, s: dict, out: Path) -> None:
    rows = _pipeline_rows(s["pipeline"])
    fig, ax = plt.subplots(figsize=(6.5, 0.9 + 0.55 * len(rows)))
    ypos = np.arange(len(rows))
    ax.barh(ypos - 0.2, [r[1] for r in rows], 0.4, label="wall")
    if any(np.isfinite(r[2]) for r in rows):
        ax.barh(ypos + 0.2, [r[2] for r in rows], 0.4, label="CPU (all threads)")
        ax.legend(fontsize=8)
    ax.set_yticks(ypos)
    ax.set_yticklabels([r[0] for r in rows], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("median s per pair (features + matching + pose)")
    ax.set_title(
        f"Whole-pair time, {s['pipeline']['pairs']} {s['pipeline']['source']} pairs", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(out / FILES["pipeline"], dpi=110)
    plt.close(fig)


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.3f} ms" if seconds < 1 else f"{seconds:.2f} s"


def _auc_cell(entry: dict) -> str:
    return " / ".join(f"{a:.1f}" for a in entry["auc"])


def headline(s: dict) -> str:
    """The headline table: real-pair and rendered AUC, identification speed, detection."""
    acc = s["accuracy"]
    cols = ["ppo_cv", "opencv", "pycolmap", "pycolmap relpose", "poselib"]
    lines = [
        "| | " + " | ".join(LABELS[c] for c in cols) + " |",
        "|---|" + "---:|" * len(cols),
    ]
    for name in ("freiburg", "rendered, all presets"):
        if name in acc:
            lines.append(
                f"| AUC@5/10/20, {name} ({acc[name]['pairs']} pairs) | "
                + " | ".join(_auc_cell(acc[name][c]) for c in cols)
                + " |"
            )
    ident = {r["n"]: r for r in s["identification"]}
    for n in (1000, 100_000):
        if n in ident:
            r = ident[n]
            lines.append(
                f"| pose identification, N = {n:,} (from E) | {_ms(r['ppo_cv.recoverPose'])} | "
                f"{_ms(r['cv2.recoverPose'])} | {_ms(r['pycolmap pose from E'])} | | |"
            )
    det = s["detection"]
    ours = det.get(OUR_DETECTOR)
    pano = det.get("pycolmap: PANORAMIC or PLANAR_OR_PANORAMIC")
    if ours and pano:
        lines.append(
            "| pure-rotation detection, precision / recall (pycolmap: PANORAMIC or "
            f"PLANAR_OR_PANORAMIC) | {_pct(ours['precision'])} / {_pct(ours['recall'])} | | "
            f"{_pct(pano['precision'])} / {_pct(pano['recall'])} | | |"
        )
    return "\n".join(lines)


def _pct(x: float) -> str:
    return "n/a" if not np.isfinite(x) else f"{100 * x:.0f} %"


def _pure_rotation_sets(saved: dict) -> dict[str, list[dict]]:
    """The rows of the main sets of ``pure_rotation.py`` (not the sweep, not the ablation with
    the focal ratio held), per group of :data:`PURE_ROTATION_GROUPS`, with a pose."""
    groups: dict[str, list[dict]] = {group: [] for group in PURE_ROTATION_GROUPS}
    for name, data in saved.items():
        if not main_set(name, data):
            continue
        for group, member in PURE_ROTATION_GROUPS.items():
            if member(name, data["label"]):
                groups[group] += evaluated(data["rows"])
    return groups


def _precision_recall(saved: dict, key: str) -> str:
    true, flagged, positives = flag_counts(saved, key)
    return f"precision {true} / {flagged}, recall {true} / {positives}"


def pure_rotation_lines(figdir: str, path: Path = PURE_ROTATION_ROWS) -> list[str]:
    """Markdown summary of ``pure_rotation.py``'s rows (``path``): the flag rates and median
    rotation errors per group of sets, the precision and recall over them, and its plot in
    ``figdir``; [] without rows."""
    if not path.is_file():
        return []
    saved = json.loads(path.read_text())
    groups = _pure_rotation_sets(saved)
    lines = [
        f"Summary of that report ({saved['_seconds']:.0f} s run, rows in "
        "`benchmarks/pure_rotation.json`): the share of pairs flagged as pure rotations, and "
        "the median / max rotation error (degrees) of each method on the same matches.",
        "",
        "| sets | pairs | ppo_cv flagged | pycolmap flagged | "
        + " | ".join(f"{m} R err" for m in PURE_ROTATION_METHODS.values())
        + " |",
        "|---|---:|---:|---:|" + "---:|" * len(PURE_ROTATION_METHODS),
    ]
    for group, rows in groups.items():
        if not rows:
            continue
        rates = [
            np.mean([bool(r[k]) for r in rows if k in r]) for k in ("ppo_cv_flag", "pycolmap_flag")
        ]
        errors = [
            np.array([r[k] for r in rows if np.isfinite(r.get(k, np.nan))])
            for k in PURE_ROTATION_METHODS
        ]
        lines.append(
            f"| {group} | {len(rows)} | {_pct(rates[0])} | {_pct(rates[1])} | "
            + " | ".join(f"{np.median(e):.2f} / {np.max(e):.2f}" if e.size else "-" for e in errors)
            + " |"
        )
    lines += [
        "",
        "True flags over all flags and over all pure rotations and tripod pans: ppo_cv "
        f"{_precision_recall(saved, 'ppo_cv_flag')}; pycolmap PANORAMIC or "
        f"PLANAR_OR_PANORAMIC {_precision_recall(saved, 'pycolmap_flag')}. The decision "
        "statistic of every pair, pure rotations against translating pairs:",
        "",
        f"![decision statistic]({figdir}/pure_rotation_statistic.png)",
        "",
    ]
    return lines


def _stage_lines(pipe: dict, stages: dict) -> list[str]:
    """The table of ``estimate_pair``'s stages: median wall time, and when measured the median
    CPU time and the CPU time of the median pair, beside the baseline's."""
    base = pipe.get("baseline") or {}
    cpu, median_pair = pipe.get("stage_cpu"), pipe.get("median_pair")
    columns = [("median wall ms", stages)]
    if cpu:
        columns.append(("median CPU ms", cpu))
    if median_pair:
        columns.append(("CPU ms of the median pair", median_pair["stage_cpu"]))
    for name, key in (("wall", "stages"), ("CPU", "stage_cpu")):
        if base.get(key):
            columns.append((f"median {name} ms, {base['label']}", base[key]))
    lines = [
        "",
        "Each stage of `estimate_pair` over the same pairs: wall time from "
        "`PairResult.timings`"
        + (
            ", CPU time (all threads) read as `estimate_pair(progress=...)` reports each "
            "stage's end"
            if cpu
            else ""
        )
        + (
            f"; the median pair is the one whose total CPU time is the median "
            f"({median_pair['cpu']:.3f} s; of an even number, the lower middle)"
            if median_pair
            else ""
        )
        + ":",
        "",
        "| stage | " + " | ".join(name for name, _ in columns) + " |",
        "|---|" + "---:|" * len(columns),
    ]
    for stage in stages:
        cells = [
            f"{values[stage] * 1e3:.1f}" if stage in values else "" for _, values in columns
        ]
        lines.append(f"| {stage} | " + " | ".join(cells) + " |")
    return lines


def pipeline_lines(pipe: dict, figdir: str) -> list[str]:
    """Section 4: median wall and CPU time per pair, the stages of ``estimate_pair``, the
    machine."""
    lines = [
        "",
        "## 4. Whole-pair time",
        "",
        f"![pipeline]({figdir}/{FILES['pipeline']})",
        "",
        f"Median wall time per pair over {pipe['pairs']} {pipe['source']} pairs, one pair at a "
        "time in one process, features and matching included. The OpenCV pipeline is SIFT + "
        "`findEssentialMat` (USAC_MAGSAC) + `recoverPose`; the pycolmap pipeline is the same "
        "SIFT matches + `estimate_calibrated_two_view_geometry` + "
        "`estimate_two_view_geometry_pose`.",
    ]
    if "OpenCV SIFT alone" in pipe:
        lines[-1] += (
            " `OpenCV SIFT alone` is the detection of the OpenCV pipeline (both images), the "
            "floor under each pipeline."
        )
    if "cpu" in pipe:
        lines[-1] += (
            " CPU time is `time.process_time()`, summed over the threads of the process: "
            "`estimate_pair` detects the two images on two threads (OpenCV itself on one, "
            "`cv2.setNumThreads(1)`), the other pipelines one after the other."
        )
    if "command" in pipe:
        lines += ["", "Made by", "", "```", pipe["command"].strip(), "```"]
    machine = pipe.get("machine")
    if machine:
        lines += [
            "",
            f"on {machine['cpu']}, {machine['cores']} logical cores, 1-minute load average "
            f"{machine['load']:.2f} at the start and {machine['load_after']:.2f} at the end "
            "(a shared host: the load is other work).",
        ]
    has_cpu = "cpu" in pipe
    lines += [
        "",
        "| pipeline | median wall s / pair |" + (" median CPU s / pair |" if has_cpu else ""),
        "|---|---:|" + ("---:|" if has_cpu else ""),
    ]
    for label, wall, cpu in _pipeline_rows(pipe):
        lines.append(f"| {label} | {wall:.3f} |" + (f" {cpu:.3f} |" if has_cpu else ""))
    if pipe.get("per_pair"):
        lines += per_pair_lines(pipe["per_pair"])
    stages = pipe.get("stages")
    if stages:
        lines += _stage_lines(pipe, stages)
    return lines


def per_pair_lines(per_pair: list[dict]) -> list[str]:
    """How many pairs ``estimate_pair`` takes at most the OpenCV pipeline's time on, by wall
    and by CPU time, and the table of each pair."""
    wall = sum(row["wall"] <= row["opencv_wall"] for row in per_pair)
    cpu = sum(row["cpu"] <= row["opencv_cpu"] for row in per_pair)
    lines = [
        "",
        f"Pairs on which `estimate_pair` took at most the OpenCV pipeline's time in this run: "
        f"{wall} of {len(per_pair)} by wall time, {cpu} of {len(per_pair)} by CPU time "
        "(detections: 1 for a pair whose first consensus holds, 2 for a weak pair detected "
        "again at the lower threshold):",
        "",
        "| pair | estimate_pair wall / CPU s | OpenCV pipeline wall / CPU s | detections |",
        "|---:|---:|---:|---:|",
    ]
    for index, row in enumerate(per_pair):
        lines.append(
            f"| {index} | {row['wall']:.3f} / {row['cpu']:.3f} | "
            f"{row['opencv_wall']:.3f} / {row['opencv_cpu']:.3f} | {row['detections']} |"
        )
    return lines


def render(res: dict, s: dict, figdir: str) -> str:
    st = s["settings"]
    v = st["versions"]
    lines = [
        "# Benchmarks: ppo_cv against OpenCV, pycolmap and PoseLib",
        "",
        "Every number on this page comes from one run of",
        "",
        "```",
        st["command"].strip(),
        "```",
        "",
        f"on 2 cores ({st['total_seconds']:.0f} s; Python {v['python']}, numpy {v['numpy']}, "
        f"OpenCV {v['opencv']}, pycolmap {v['pycolmap']}, PoseLib {v['poselib']}, "
        f"ppo_cv {v['ppo_cv']}). Raw numbers: `{figdir}/results.json`. PoseLib is a "
        'benchmark-only extra (`pip install ".[bench]"`).',
        "",
        "## Headline",
        "",
        headline(s),
        "",
        "## 1. Pose identification time (same E, same points)",
        "",
        f"![identification]({figdir}/{FILES['speed']})",
        "",
        "The exact essential matrix of one pose of the paper's protocol (d = 30 m, alpha 0.5, "
        "1 px noise) and its N matches; median of interleaved calls, OpenCV on one thread. "
        "pycolmap's pose from E is `estimate_two_view_geometry_pose` on a CALIBRATED "
        "`TwoViewGeometry` carrying E, which triangulates for cheirality as OpenCV does.",
        "",
        "| N | ppo_cv.recoverPose | cv2.recoverPose | pycolmap pose from E | cv2 / ppo_cv "
        "| pycolmap / ppo_cv |",
        "|---:|---:|---:|---:|---:|---:|",
    ]
    for r in s["identification"]:
        lines.append(
            f"| {r['n']:,} | {_ms(r['ppo_cv.recoverPose'])} | {_ms(r['cv2.recoverPose'])} "
            f"| {_ms(r['pycolmap pose from E'])} | {r['cv2_ratio']:.1f}x | "
            f"{r['pycolmap_ratio']:.1f}x |"
        )
    lines += [
        "",
        "## 2. Accuracy: AUC of the pose error",
        "",
        f"![AUC]({figdir}/{FILES['auc']})",
        "",
        "Pose error = max(rotation error, angle between translation directions, sign ignored); "
        "for pure rotations (t = 0) the rotation error alone. A failure counts as 180 deg. "
        f"Rendered pairs: {st['pairs_per_motion']} per motion preset of `ppo_cv.data_gen` "
        f"(seed {st['seed']}, 640x480). The anchors share OpenCV SIFT matches (4000 features, "
        "ratio 0.8); `ppo_cv estimate_pair` runs its own default pipeline on the same images; "
        "`OpenCV E + ppo_cv.recoverPose` is OpenCV's pipeline with only the pose "
        "identification replaced (the drop-in use).",
        "",
        "| pairs | n | " + " | ".join(LABELS.values()) + " |",
        "|---|---:|" + "---:|" * len(LABELS),
    ]
    for name, entry in s["accuracy"].items():
        cells = []
        for method in LABELS:
            cell = _auc_cell(entry[method])
            if entry[method]["failed"]:
                cell += f" ({entry[method]['failed']} failed)"
            cells.append(cell)
        lines.append(f"| {name} | {entry['pairs']} | " + " | ".join(cells) + " |")
    counts = s["detection_counts"]
    lines += [
        "",
        "Cells: AUC@5 / AUC@10 / AUC@20 in %.",
        "",
        "## 3. Pure-rotation detection",
        "",
        "Pure rotations with the imperfections of real photos (unmodelled distortion, focal "
        "error, narrow field), warped photos and real translating pairs, with the model "
        "comparison of `estimate_pair` next to pycolmap's PANORAMIC configuration: "
        "[pure_rotation.md](pure_rotation.md) (`benchmarks/pure_rotation.py`).",
        "",
        *pure_rotation_lines(figdir),
        "Below, the clean renders of this run.",
        "",
        f"![detection]({figdir}/{FILES['detection']})",
        "",
        "Positives: the rendered pure-rotation pairs (t = 0 exactly); negatives: small-parallax, "
        "planar and general pairs (" + ", ".join(f"{n} {m}" for m, n in counts.items()) + "). "
        "M3 is computed on the inliers and rotation of `estimate_pair`. The last row uses the M3 "
        "threshold that separates these very pairs best, an optimistic bound that no fixed "
        "threshold reaches on unseen data. Small-parallax pairs with a tiny parallax factor are "
        "nearly pure rotations, so flags there are expected for the smallest alphas.",
        "",
        "| detector | precision | recall | "
        + " | ".join(f"flagged: {m}" for m in DETECTION_MOTIONS)
        + " |",
        "|---|---:|---:|" + "---:|" * len(DETECTION_MOTIONS),
    ]
    for name, d in s["detection"].items():
        lines.append(
            f"| {name} | {_pct(d['precision'])} | {_pct(d['recall'])} | "
            + " | ".join(_pct(d["rates"].get(m, np.nan)) for m in DETECTION_MOTIONS)
            + " |"
        )
    small = sorted(
        (r for r in res["pairs"] if r.get("motion") == "small-parallax"),
        key=lambda r: r.get("alpha") or 0.0,
    )
    if small:
        lines += [
            "",
            "The small-parallax pairs one by one (parallax factor alpha: baseline = alpha x 0.14 x "
            "scene depth):",
            "",
            "| alpha | ppo_cv flag | PRI | M3 | pycolmap configuration | ppo_cv pose error (deg) |",
            "|---:|:---:|---:|---:|---|---:|",
        ]
        for r in small:
            ours = r["methods"]["ppo_cv"]
            flag = "yes" if ours.get("pure_rotation") else ""
            pri, m3 = ours.get("pri", float("nan")), ours.get("m3", float("nan"))
            config = r["methods"]["pycolmap"].get("config", "")
            lines.append(
                f"| {r.get('alpha') or float('nan'):.4f} | {flag} | {pri:.4f} | {m3:.4f} | "
                f"{config} | {ours['err']:.2f} |"
            )
    failed = {m: n for m, n in s["detection_ppo_failed"].items() if n}
    if failed:
        lines += [
            "",
            "`estimate_pair` raised an error (counted as not flagged) on "
            + ", ".join(f"{n} {m}" for m, n in failed.items())
            + " pairs.",
        ]
    lines += pipeline_lines(s["pipeline"], figdir)
    lines += [
        "",
        "## 5. Peak memory of identification",
        "",
        f"![memory]({figdir}/{FILES['memory']})",
        "",
        "One fresh interpreter per row; `traced` is the tracemalloc peak of the call (numpy "
        "allocations; OpenCV's C++ buffers are invisible to it), `RSS` the rise of the resident "
        "high-water mark (sees both). `ppo_cv.recover_pose` also returns the analytic points and "
        "depths of every match (40 bytes per point of output).",
        "",
        "| method | N | traced peak | traced bytes / point | RSS peak rise | RSS bytes / point |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in s["memory"]:
        rss = r["rss_bytes"]
        lines.append(
            f"| {r['method']} | {r['n']:,} | {r['traced_bytes'] / 2**20:.1f} MiB | "
            f"{r['traced_bytes'] / r['n']:.0f} | "
            f"{'n/a' if rss is None else f'{rss / 2**20:.1f} MiB'} | "
            f"{'n/a' if rss is None else round(rss / r['n'])} |"
        )
    lines += ["", "## Where ppo_cv is ahead", ""]
    lines += [f"- {win}" for win in s["wins"]] or ["Nowhere in this run."]
    lines += ["", "## Where ppo_cv is behind", ""]
    if s["losses"]:
        lines += [f"- {loss}" for loss in s["losses"]]
    else:
        lines.append("Nowhere in this run.")
    lines.append("")
    return "\n".join(lines)


KEPT_FROM = "## 6."


def kept_sections(report: Path) -> str:
    """The sections of an existing report from ``## 6.`` on, made by other scripts.

    Sections 1-5 and the summaries are this script's; later ones (the model choice of
    ``model_choice.py``) are regenerated by their own commands and carried over unchanged.
    """
    if not report.is_file():
        return ""
    text = report.read_text()
    start = text.find("\n" + KEPT_FROM)
    return "" if start < 0 else "\n" + text[start + 1 :].rstrip("\n") + "\n"


if __name__ == "__main__":
    raise SystemExit(
        "compare_report.py is a module of compare.py, not a script; run "
        "python benchmarks/compare.py --help"
    )
