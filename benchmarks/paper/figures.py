"""Matplotlib figures of the paper reproduction, one PNG per paper figure."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LogNorm, TwoSlopeNorm  # noqa: E402

__all__ = ["draw_all", "FILES"]

FILES = {
    "fig4": "fig04_pose_discrepancy.png",
    "fig5": "fig05_translation_difference.png",
    "fig6": "fig06_translation_difference_averages.png",
    "fig7": "fig07_reconstruction_ratio.png",
    "fig11": "fig11_pri_m3.png",
    "fig13": "fig13_identification_time.png",
}


def _heatmap(ax, res: dict, values: np.ndarray, title: str, label: str, **kwargs):
    """Noise on x, parallax factor (log) on y, as in the paper's figures."""
    noises, alphas = np.asarray(res["noises"]), np.asarray(res["alphas"])
    mesh = ax.pcolormesh(noises, alphas, values, shading="nearest", **kwargs)
    ax.set_yscale("log")
    ax.set_xlabel("noise standard deviation (px)")
    ax.set_ylabel("parallax factor alpha")
    ax.set_title(title, fontsize=10)
    ax.figure.colorbar(mesh, ax=ax, label=label)
    return mesh


def _save(fig, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _diverging(values: np.ndarray) -> TwoSlopeNorm:
    span = float(np.nanmax(np.abs(values))) or 1.0
    return TwoSlopeNorm(vcenter=0.0, vmin=-span, vmax=span)


def draw_all(res: dict, out: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    _heatmap(
        axes[0], res, res["fig4_rot_rmse"], "Fig. 4(a) rotation discrepancy, PPO", "RMSE (deg)"
    )
    _heatmap(
        axes[1],
        res,
        res["fig4_t_rmse"],
        "Fig. 4(b) translation discrepancy, PPO",
        "RMSE (deg)",
        vmin=0,
        vmax=max(90.0, float(np.nanmax(res["fig4_t_rmse"]))),
    )
    _save(fig, out / FILES["fig4"])

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, name in (
        (axes[0], "fig5_diff_cv_d30", "cv2.recoverPose (distanceThresh 50)"),
        (axes[1], "fig5_diff_cheir_d30", "cheirality, no distance cut"),
    ):
        values = np.asarray(res[key])
        _heatmap(
            ax,
            res,
            values,
            f"Fig. 5 {name} minus PPO, d = 30 m",
            "deg",
            cmap="RdBu_r",
            norm=_diverging(values),
        )
    _save(fig, out / FILES["fig5"])

    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex="col")
    for row, (prefix, name) in enumerate(
        (("fig5_diff_cv", "cv2.recoverPose"), ("fig5_diff_cheir", "cheirality, no cut"))
    ):
        for d in res["depths"]:
            grid = np.asarray(res[f"{prefix}_d{d:g}"])
            axes[row, 0].plot(
                res["noises"], np.nanmean(grid, axis=0), marker=".", label=f"d = {d:g} m"
            )
            axes[row, 1].plot(
                res["alphas"], np.nanmean(grid, axis=1), marker=".", label=f"d = {d:g} m"
            )
        axes[row, 0].set_title(f"Fig. 6(a) {name} minus PPO, mean over alpha", fontsize=10)
        axes[row, 1].set_title(f"Fig. 6(b) {name} minus PPO, mean over noise", fontsize=10)
        axes[row, 1].set_xscale("log")
        for ax in axes[row]:
            ax.axhline(0.0, color="k", lw=0.7)
            ax.set_ylabel("translation discrepancy difference (deg)")
            ax.legend(fontsize=8)
    axes[1, 0].set_xlabel("noise standard deviation (px)")
    axes[1, 1].set_xlabel("parallax factor alpha")
    _save(fig, out / FILES["fig6"])

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, name in (
        (axes[0], "fig7_ratio_rmse", "RMSE ratio (paper's eq. 83)"),
        (axes[1], "fig7_ratio_median", "median-error ratio"),
    ):
        values = np.asarray(res[key])
        _heatmap(
            ax,
            res,
            values,
            f"Fig. 7 analytic / DLT 3D error, {name}",
            "ratio",
            cmap="RdBu_r",
            norm=LogNorm(vmin=min(np.nanmin(values), 0.99), vmax=max(np.nanmax(values), 1.01)),
        )
    _save(fig, out / FILES["fig7"])

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    pri, m3 = np.asarray(res["fig11_pri"]), np.asarray(res["fig11_m3"])
    _heatmap(axes[0], res, pri, "Fig. 11(a) PRI (mean over problems)", "PRI", norm=LogNorm())
    axes[0].contour(res["noises"], res["alphas"], pri, levels=[0.015], colors="magenta")
    axes[0].contour(
        res["noises"],
        res["alphas"],
        np.asarray(res["fig4_t_rmse"]),
        levels=[45.0],
        colors="white",
        linestyles="dashed",
    )
    _heatmap(axes[1], res, m3, "Fig. 11(b) M3 (mean over problems)", "M3", norm=LogNorm())
    axes[1].contour(
        res["noises"],
        res["alphas"],
        np.asarray(res["fig4_t_rmse"]),
        levels=[45.0],
        colors="white",
        linestyles="dashed",
    )
    _save(fig, out / FILES["fig11"])

    sizes = np.asarray(res["fig13_sizes"])
    seconds = {k: np.asarray(v) for k, v in res["fig13_seconds"].items()}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, values in seconds.items():
        axes[0].loglog(sizes, values * 1e3, marker="o", label=name)
    axes[0].set_xlabel("number of points")
    axes[0].set_ylabel("median time per call (ms)")
    axes[0].set_title("Fig. 13(a) identification time", fontsize=10)
    axes[0].legend(fontsize=8)
    names = list(seconds)
    for trad in names[2:]:
        for method in names[:2]:
            axes[1].semilogx(
                sizes, seconds[trad] / seconds[method], marker="o", label=f"{trad} / {method}"
            )
    axes[1].axhline(1.0, color="k", lw=0.7)
    axes[1].set_xlabel("number of points")
    axes[1].set_ylabel("time ratio")
    axes[1].set_title("Fig. 13(b) traditional over PPO", fontsize=10)
    axes[1].legend(fontsize=7)
    _save(fig, out / FILES["fig13"])
