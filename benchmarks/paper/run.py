"""Reproduce the simulation results of Cai et al. (Section 5) with ppo_cv: figures and report.

Usage (from the repository root, after ``pip install ".[bench]"``)::

    python benchmarks/paper/run.py --out docs/paper --report docs/paper_reproduction.md

Keeps the paper's grids (parallax factor 1e-3 ... 1 on a log grid, noise 0.1 ... 5 px) with
fewer grid points and Monte-Carlo draws: ``--grid``, ``--poses`` and ``--runs`` set them
(paper: 200 noise levels, 200 poses, 30 runs). ``--jobs`` worker processes share the cells.
Writes one PNG per figure, ``results.json`` with every plotted number, and the markdown report.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import figures  # noqa: E402
import report  # noqa: E402
from simulation import euler_zyx_deg, linear_essential, rmse, simulate_cell  # noqa: E402
from timing import METHODS, time_methods  # noqa: E402

from ppo_cv import ppo  # noqa: E402
from ppo_cv.data_gen import euler_to_matrix, paper_protocol  # noqa: E402

DEPTHS = (30.0, 50.0, 80.0)
BAD_T_DEG = 45.0
TIMING_SIZES = (10, 30, 100, 300, 1000, 3000, 10000)


def _init_worker() -> None:
    cv2.setNumThreads(1)


def _cell(args: tuple) -> tuple:
    (ia, inoise, depth, alpha, noise, n_poses, n_mc, with_3d) = args
    return ia, inoise, depth, simulate_cell(alpha, noise, depth, n_poses, n_mc, with_3d=with_3d)


def run_grid(alphas, noises, n_poses: int, n_mc: int, jobs: int) -> dict:
    """All cells of all depths; 3D errors only at d = 30 m (the paper's Fig. 7 setting)."""
    tasks = [
        (ia, inz, d, a, nz, n_poses, n_mc, d == DEPTHS[0])
        for d in DEPTHS
        for ia, a in enumerate(alphas)
        for inz, nz in enumerate(noises)
    ]
    cells: dict = {}
    with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker) as pool:
        for ia, inz, d, cell in pool.map(_cell, tasks, chunksize=4):
            cells[(d, ia, inz)] = cell
    return cells


def _grid(cells: dict, depth: float, shape: tuple, fn) -> np.ndarray:
    out = np.full(shape, np.nan)
    for ia in range(shape[0]):
        for inz in range(shape[1]):
            out[ia, inz] = fn(cells[(depth, ia, inz)])
    return out


def _ratio_3d(c) -> float:
    n = c.n3d.sum()
    return float(np.sqrt(c.sq3d_anal.sum() / n) / np.sqrt(c.sq3d_dlt.sum() / n))


def _roc(scores: np.ndarray, positive: np.ndarray) -> dict:
    """Separation of ``positive`` cases by ``score < threshold``: AUC and the best threshold."""
    order = np.argsort(scores)
    s, pos = scores[order], positive[order]
    tpr = np.concatenate([[0.0], np.cumsum(pos) / max(pos.sum(), 1)])
    fpr = np.concatenate([[0.0], np.cumsum(~pos) / max((~pos).sum(), 1)])
    auc = float(np.trapezoid(tpr, fpr))
    j = int(np.argmax(tpr - fpr))
    threshold = (
        float(s[j - 1] if j == len(s) else (s[max(j - 1, 0)] + s[j]) / 2) if j else float(s[0])
    )
    return {
        "auc": auc,
        "best_threshold": threshold,
        "best_tpr": float(tpr[j]),
        "best_fpr": float(fpr[j]),
    }


def _rates(scores: np.ndarray, positive: np.ndarray, threshold: float) -> dict:
    flagged = scores < threshold
    return {
        "tpr": float(np.mean(flagged[positive])) if positive.any() else float("nan"),
        "fpr": float(np.mean(flagged[~positive])) if (~positive).any() else float("nan"),
        "precision": float(np.mean(positive[flagged])) if flagged.any() else float("nan"),
    }


def summarise(cells: dict, alphas: np.ndarray, noises: np.ndarray) -> dict:
    shape = (len(alphas), len(noises))
    d0 = DEPTHS[0]
    res: dict = {"alphas": alphas.tolist(), "noises": noises.tolist(), "depths": list(DEPTHS)}
    res["fig4_rot_rmse"] = _grid(cells, d0, shape, lambda c: rmse(c.rot_ppo))
    res["fig4_t_rmse"] = _grid(cells, d0, shape, lambda c: rmse(c.t_ppo))
    res["fig4_rot_rmse_cv"] = _grid(cells, d0, shape, lambda c: rmse(c.rot_cv))
    for d in DEPTHS:
        res[f"fig5_diff_cv_d{d:g}"] = _grid(cells, d, shape, lambda c: rmse(c.t_cv) - rmse(c.t_ppo))
        res[f"fig5_diff_cheir_d{d:g}"] = _grid(
            cells, d, shape, lambda c: rmse(c.t_cheir) - rmse(c.t_ppo)
        )
        all_cells = [cells[(d, ia, inz)] for ia in range(shape[0]) for inz in range(shape[1])]
        res[f"rot_right_ppo_d{d:g}"] = float(
            np.mean(np.concatenate([c.rot_right_ppo for c in all_cells]))
        )
        res[f"rot_right_cv_d{d:g}"] = float(
            np.mean(np.concatenate([c.rot_right_cv for c in all_cells]))
        )
        t_err = np.concatenate([c.t_ppo for c in all_cells])
        pri = np.concatenate([c.pri for c in all_cells])
        m3 = np.concatenate([c.m3 for c in all_cells])
        bad = t_err > BAD_T_DEG
        res[f"sep_d{d:g}"] = {
            "n_problems": int(bad.size),
            "n_bad": int(bad.sum()),
            "pri": _roc(pri, bad),
            "m3": _roc(m3, bad),
            "pri_at_0.015": _rates(pri, bad, ppo.DEFAULT_PRI_THRESHOLD),
        }
    res["fig7_ratio_rmse"] = _grid(cells, d0, shape, _ratio_3d)
    res["fig7_ratio_median"] = _grid(
        cells, d0, shape, lambda c: float(np.median(c.med3d_anal) / np.median(c.med3d_dlt))
    )
    res["fig11_pri"] = _grid(cells, d0, shape, lambda c: float(np.mean(c.pri)))
    res["fig11_m3"] = _grid(cells, d0, shape, lambda c: float(np.mean(c.m3)))
    return res


def table3(seed: int = 0) -> dict:
    """The four candidates of ``Q`` for the paper's pure-rotation case (Euler (10, -5, 2), t = 0).

    Noise-free points of the protocol's scene; ``Q`` is the linear solution (eq. 42), here an
    arbitrary member of the three-dimensional family ``R [a]x`` (eq. 52).
    """
    euler = np.array([10.0, -5.0, 2.0])
    s = paper_protocol(1, 50, alpha=0.0, noise_px=0.0, seed=seed)
    X = s.points3d[0]
    R = euler_to_matrix(euler)
    x1 = np.c_[X[:, :2] / X[:, 2:], np.ones(len(X))]
    X2 = X @ R.T
    x2 = np.c_[X2[:, :2] / X2[:, 2:], np.ones(len(X))]
    Q = linear_essential(x1[None], x2[None])[0]
    cand = ppo.decompose_essential(Q)
    sel = ppo.select_pose(Q, x1, x2)
    rows = []
    for Rc, tc in ((cand.R1, cand.t), (cand.R2, cand.t), (cand.R1, -cand.t), (cand.R2, -cand.t)):
        rows.append(
            {
                "euler_deg": euler_zyx_deg(Rc).tolist(),
                "t": tc.tolist(),
                "chosen": bool(np.allclose(Rc, sel.R) and np.allclose(tc, sel.t)),
            }
        )
    _, R_cv, t_cv, _ = cv2.recoverPose(Q, x1[:, :2].copy(), x2[:, :2].copy(), np.eye(3))
    return {
        "true_euler_deg": euler.tolist(),
        "noise_px": 0.0,
        "candidates": rows,
        "pri": ppo.pure_rotation_indicator(sel.m2),
        "pure_rotation": bool(ppo.pure_rotation_indicator(sel.m2) < ppo.DEFAULT_PRI_THRESHOLD),
        "m3": ppo.m3_indicator(x1, x2, sel.R),
        "opencv_euler_deg": euler_zyx_deg(R_cv).tolist(),
        "opencv_t": t_cv.ravel().tolist(),
    }


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return (
            np.where(np.isfinite(value), value, None).tolist()
            if value.dtype.kind == "f"
            else value.tolist()
        )
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    return value


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Reproduce the paper's simulation figures.")
    parser.add_argument("--out", type=Path, default=Path("docs/paper"), help="figure directory")
    parser.add_argument("--report", type=Path, default=Path("docs/paper_reproduction.md"))
    parser.add_argument("--grid", type=int, default=16, help="grid points per axis (paper: 200)")
    parser.add_argument("--poses", type=int, default=40, help="poses per cell (paper: 200)")
    parser.add_argument("--runs", type=int, default=3, help="Monte-Carlo runs (paper: 30)")
    parser.add_argument("--timing-runs", type=int, default=20, help="runs per N for Fig. 13")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    start = time.perf_counter()
    alphas = np.logspace(-3, 0, args.grid)
    noises = np.linspace(0.1, 5.0, args.grid)
    cells = run_grid(alphas, noises, args.poses, args.runs, args.jobs)
    grid_seconds = time.perf_counter() - start
    res = summarise(cells, alphas, noises)
    res["table3"] = table3()
    t0 = time.perf_counter()
    timing = time_methods(TIMING_SIZES, n_runs=args.timing_runs)
    res["fig13_sizes"] = list(TIMING_SIZES)
    res["fig13_seconds"] = {k: v.tolist() for k, v in timing.items()}
    res["settings"] = {
        "grid": args.grid,
        "poses": args.poses,
        "runs": args.runs,
        "points": 50,
        "timing_runs": args.timing_runs,
        "jobs": args.jobs,
        "bad_t_deg": BAD_T_DEG,
        "grid_seconds": round(grid_seconds, 1),
        "timing_seconds": round(time.perf_counter() - t0, 1),
        "total_seconds": round(time.perf_counter() - start, 1),
        "command": "python benchmarks/paper/run.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "opencv": cv2.__version__,
        },
        "methods_fig13": list(METHODS),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    figures.draw_all(res, args.out)
    (args.out / "results.json").write_text(json.dumps(_jsonable(res), indent=1))
    args.report.parent.mkdir(parents=True, exist_ok=True)
    args.report.write_text(report.render(res, os.path.relpath(args.out, args.report.parent)))
    print(
        f"wrote {args.out}/*.png, {args.out}/results.json and {args.report} "
        f"in {time.perf_counter() - start:.0f} s"
    )


if __name__ == "__main__":
    main()
