"""The paper's protocol with the points on a plane: which homography decomposition is picked.

Usage (from the repository root, after ``pip install ".[bench]"``)::

    python benchmarks/paper/planar.py --out docs/paper --report docs/paper_reproduction.md

Each problem takes the cameras of :func:`ppo_cv.data_gen.paper_protocol` (K, Euler angles
N(0, diag(5^2, 5^2, 20^2)) deg, translation alpha * 4.2 m in the OXY plane) and moves its 50
points along the rays of camera 1 onto a plane through (0, 0, d), d = 30 m, whose normal leans
U(0, 30) deg from the optical axis in a uniform direction: the image of view 1 keeps the paper's
point distribution (rays up to 55 deg off axis, so a steeper plane would meet some rays behind
the camera). Both
views get Gaussian pixel noise. The homography is the least-squares fit to the 50 matches
(``cv2.findHomography`` with method 0, the counterpart of the paper's linear ``Q``, eq. 42),
normalized and decomposed once (:func:`ppo_cv.plane.decompose_homography`), and three rules
choose among the same four candidates:

``PPO``
    :func:`ppo_cv.plane.select_plane_pose`: most points with ``M1 > 0`` and ``M2 > 0``
    (eq. 70, 76), ties by the frontality prior;
``OpenCV visibility``
    ``cv2.filterHomographyDecompByVisibleRefpoints`` on the normalized points: right only when
    it keeps exactly one candidate and it is the true one;
``positive depth``
    ``pycolmap.pose_from_homography_matrix``: the candidate with the most triangulated points
    in front of both cameras (COLMAP's cheirality test).

The true candidate is the one nearest to the ground truth (rotation error plus translation
direction error). The script prints the table, draws the figure and writes its section of the
report between markers, replacing an earlier one (run it after ``run.py``, which rewrites the
whole page).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from ppo_cv.data_gen import paper_protocol  # noqa: E402
from ppo_cv.metrics import direction_error_deg, rotation_error_deg  # noqa: E402
from ppo_cv.plane import decompose_homography, normalize_homography, select_plane_pose  # noqa: E402

__all__ = ["planar_protocol", "choose_all", "run_grid", "main"]

ALPHAS = (0.05, 0.2, 1.0)
NOISES = (0.0, 0.5, 1.0, 2.0, 3.0, 5.0)
METHODS = ("PPO", "OpenCV visibility", "positive depth")
TILT_DEG = 30.0
FIGURE = "fig_planar_decomposition.png"
BEGIN = "<!-- planar-decomposition: begin -->"
END = "<!-- planar-decomposition: end -->"


@dataclass(frozen=True)
class PlanarSample:
    """Normalized points (P, N, 3) of both views and the truth (R, t, plane normal n)."""

    x1: np.ndarray
    x2: np.ndarray
    R: np.ndarray
    t: np.ndarray
    n: np.ndarray


def planar_protocol(
    n_poses: int, alpha: float, noise_px: float, seed: int = 0, mc_run: int = 0, depth=30.0
) -> PlanarSample:
    """The paper's cameras and image points with the scene replaced by a tilted plane."""
    s = paper_protocol(n_poses, 50, alpha, 0.0, depth=depth, seed=seed, mc_run=mc_run)
    rng_plane = np.random.default_rng([seed, 13])
    rng_noise = np.random.default_rng([seed, 14, mc_run])
    tilt = np.radians(rng_plane.uniform(0.0, TILT_DEG, n_poses))
    azimuth = rng_plane.uniform(0.0, 2.0 * np.pi, n_poses)
    n = np.column_stack(
        [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)]
    )
    offset = depth * n[:, 2]  # plane n^T X = offset through (0, 0, depth)
    X1 = s.points3d * (offset[:, None] / np.einsum("pki,pi->pk", s.points3d, n))[:, :, None]
    X2 = np.einsum("pij,pkj->pki", s.R, X1) + s.t[:, None, :]
    noise = rng_noise.standard_normal((2,) + X1.shape[:2] + (2,)) * noise_px / s.K[0, 0]
    x1, x2 = X1 / X1[..., 2:], X2 / X2[..., 2:]
    x1[..., :2] += noise[0]
    x2[..., :2] += noise[1]
    return PlanarSample(x1=x1, x2=x2, R=s.R, t=s.t, n=n)


def _errors(cand, R, t) -> np.ndarray:
    """Rotation plus translation-direction error (deg) of each candidate against the truth."""
    return rotation_error_deg(cand.R, R) + direction_error_deg(cand.t, t)


def _nearest(cand, R, t) -> int:
    gaps = [np.abs(cand.R[k] - R).sum() + np.abs(cand.t[k] - t).sum() for k in range(4)]
    return int(np.argmin(gaps))


def choose_all(x1: np.ndarray, x2: np.ndarray, R_true, t_true) -> dict:
    """Candidate chosen by each rule, the true candidate and whether PPO met a tie."""
    import pycolmap

    H, _ = cv2.findHomography(x1[:, :2], x2[:, :2], 0)
    cand = decompose_homography(normalize_homography(H, x1, x2))
    truth = int(np.argmin(_errors(cand, R_true, t_true)))
    ppo_pose = select_plane_pose(cand, x1, x2)
    kept = cv2.filterHomographyDecompByVisibleRefpoints(
        list(cand.R),
        list(cand.n.reshape(4, 3, 1)),
        x1[:, None, :2].astype(np.float32),
        x2[:, None, :2].astype(np.float32),
    )
    kept = [] if kept is None else kept.ravel().tolist()
    found = pycolmap.pose_from_homography_matrix(cand.H, np.eye(3), np.eye(3), x1, x2)
    pose = found["cam2_from_cam1"]
    t = np.asarray(pose.translation, float)
    colmap = _nearest(cand, pose.rotation.matrix(), t / max(np.linalg.norm(t), 1e-300))
    return {
        "truth": truth,
        "PPO": ppo_pose.candidate,
        "ambiguous": ppo_pose.ambiguous,
        "OpenCV visibility": kept[0] if len(kept) == 1 else -1,
        "opencv_kept": len(kept),
        "positive depth": colmap,
    }


def run_grid(poses: int, runs: int, seed: int) -> list[dict]:
    """One row per (alpha, noise) cell: percentages of right choices and of ties."""
    rows = []
    for alpha in ALPHAS:
        for noise in NOISES:
            outcomes = []
            for mc in range(runs):
                s = planar_protocol(poses, alpha, noise, seed=seed, mc_run=mc)
                outcomes += [choose_all(s.x1[i], s.x2[i], s.R[i], s.t[i]) for i in range(poses)]
            row = {"alpha": alpha, "noise": noise, "problems": len(outcomes)}
            for method in METHODS:
                row[method] = 100.0 * np.mean([o[method] == o["truth"] for o in outcomes])
            amb = [o for o in outcomes if o["ambiguous"]]
            row["ambiguous"] = 100.0 * len(amb) / len(outcomes)
            row["PPO on ties"] = (
                100.0 * np.mean([o["PPO"] == o["truth"] for o in amb]) if amb else float("nan")
            )
            row["OpenCV kept 0"] = 100.0 * np.mean([o["opencv_kept"] == 0 for o in outcomes])
            row["OpenCV kept 2+"] = 100.0 * np.mean([o["opencv_kept"] > 1 for o in outcomes])
            rows.append(row)
            print(
                f"alpha {alpha:g} noise {noise:g} px: "
                + ", ".join(f"{m} {row[m]:.1f} %" for m in METHODS)
                + f", ties {row['ambiguous']:.1f} %",
                flush=True,
            )
    return rows


def _figure(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(ALPHAS), figsize=(4.2 * len(ALPHAS), 3.6), sharey=True)
    for ax, alpha in zip(axes, ALPHAS, strict=True):
        cell = [r for r in rows if r["alpha"] == alpha]
        for method, marker in zip(METHODS, "osd", strict=True):
            ax.plot(
                NOISES, [r[method] for r in cell], marker=marker, label=method,
                fillstyle="none" if method == "positive depth" else "full",
                markersize=9 if method == "positive depth" else 6,
            )  # fmt: skip
        ax.set_title(f"alpha = {alpha:g} (|t| = {alpha * 4.2:.2f} m, d = 30 m)", fontsize=10)
        ax.set_xlabel("noise standard deviation (px)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("right decomposition picked (%)")
    axes[0].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _section(rows: list[dict], args, seconds: float, figure: str) -> str:
    lines = [
        BEGIN,
        "## Extension: the pose of a plane, chosen among the decompositions of its homography",
        "",
        "Not in the paper: the PPO inequalities applied to the four candidates `(R, t, n)` of a "
        "calibrated homography instead of those of an essential matrix (`ppo_cv.plane`, "
        "`docs/homography.md`). Regenerate with",
        "",
        "```",
        "python benchmarks/paper/planar.py --out docs/paper --report docs/paper_reproduction.md",
        "```",
        "",
        "The paper's cameras and image points of view 1 (`paper_protocol`), the 50 points moved "
        f"along their rays onto a plane through (0, 0, 30 m) whose normal leans U(0, {TILT_DEG:g}) "
        f"deg from the optical axis in a uniform direction; {args.poses} poses x {args.runs} "
        "Monte-Carlo runs per cell. One least-squares homography per problem "
        "(`cv2.findHomography`, method 0), one decomposition, three rules picking among the "
        "same four candidates: PPO (most points "
        "with M1 > 0 and M2 > 0, ties by the frontality prior), OpenCV's "
        "`filterHomographyDecompByVisibleRefpoints` (right only if it keeps exactly the true "
        "candidate) and the positive-depth test of `pycolmap.pose_from_homography_matrix`. "
        f"The run took {seconds:.0f} s (Python {platform.python_version()}, numpy "
        f"{np.__version__}, OpenCV {cv2.__version__}).",
        "",
        f"![planar decomposition](paper/{figure})",
        "",
        "| alpha | noise (px) | PPO | OpenCV visibility | positive depth | ties (both "
        "interpretations valid) | PPO right on ties | OpenCV keeps none / two |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        ties = "-" if np.isnan(r["PPO on ties"]) else f"{r['PPO on ties']:.0f} %"
        lines.append(
            f"| {r['alpha']:g} | {r['noise']:g} | {r['PPO']:.1f} % | "
            f"{r['OpenCV visibility']:.1f} % | {r['positive depth']:.1f} % | "
            f"{r['ambiguous']:.1f} % | {ties} | "
            f"{r['OpenCV kept 0']:.1f} % / {r['OpenCV kept 2+']:.1f} % |"
        )
    worst = min(rows, key=lambda r: r["PPO"])
    cv_worst = min(rows, key=lambda r: r["OpenCV visibility"])
    lines += [
        "",
        f"PPO picks the true decomposition in {worst['PPO']:.1f} % of the problems or more in "
        f"every cell (lowest at alpha = {worst['alpha']:g}, {worst['noise']:g} px); OpenCV's "
        f"visibility filter falls to {cv_worst['OpenCV visibility']:.1f} % (alpha = "
        f"{cv_worst['alpha']:g}, {cv_worst['noise']:g} px), because one noisy point on the "
        "wrong side of the plane removes the true candidate (it keeps none) while PPO counts. "
        "(OpenCV also keeps both interpretations where they are both valid.) At alpha = 0.05 "
        "the baseline, 0.21 m at 30 m, moves the points by about 6 px beyond the rotation, so "
        "from 2 px of noise on the fitted homography's own translation is mostly noise and every "
        "rule misses alike. "
        "PPO and the positive-depth test count the same event (a point in front of both "
        "cameras, the paper's equivalence) and differ only where the counts tie. Ties are the "
        "two-fold ambiguity of a plane: both interpretations keep every point in front of both "
        "cameras and the images cannot decide; the frontality prior decides them.",
        END,
    ]
    return "\n".join(lines) + "\n"


def _write_section(report: Path, section: str) -> None:
    text = report.read_text() if report.exists() else ""
    if BEGIN in text and END in text:
        head, rest = text.split(BEGIN, 1)
        text = head + section.rstrip("\n") + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + section
    report.write_text(text)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/paper"))
    parser.add_argument("--report", type=Path, default=None)
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    start = time.perf_counter()
    rows = run_grid(args.poses, args.runs, args.seed)
    seconds = time.perf_counter() - start
    args.out.mkdir(parents=True, exist_ok=True)
    _figure(rows, args.out / FIGURE)
    section = _section(rows, args, seconds, FIGURE)
    print("\n" + section)
    if args.report is not None:
        _write_section(args.report, section)


if __name__ == "__main__":
    main()
