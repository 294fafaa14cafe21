"""The markdown report of the paper reproduction, written from the numbers of one run."""

from __future__ import annotations

import numpy as np
from figures import FILES

__all__ = ["render"]


def _a(res: dict, key: str) -> np.ndarray:
    return np.asarray(res[key], dtype=np.float64)


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _boundary(t_rmse: np.ndarray, alphas: np.ndarray, limit: float) -> np.ndarray:
    """Per noise column, the smallest alpha from which every larger alpha is below ``limit``."""
    out = np.full(t_rmse.shape[1], np.nan)
    for j in range(t_rmse.shape[1]):
        good = t_rmse[:, j] < limit
        k = len(alphas)
        while k > 0 and good[k - 1]:
            k -= 1
        out[j] = alphas[k] if k < len(alphas) else np.nan
    return out


def _rank_corr(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    ra = np.argsort(np.argsort(a[ok]))
    rb = np.argsort(np.argsort(b[ok]))
    return float(np.corrcoef(ra, rb)[0, 1])


def _fig4(res: dict, figdir: str) -> list[str]:
    rot, t = _a(res, "fig4_rot_rmse"), _a(res, "fig4_t_rmse")
    alphas, noises = _a(res, "alphas"), _a(res, "noises")
    bound = _boundary(t, alphas, 45.0)
    right = {d: res[f"rot_right_ppo_d{d:g}"] for d in res["depths"]}
    right_cv = {d: res[f"rot_right_cv_d{d:g}"] for d in res["depths"]}
    bad_cells = float(np.mean(t > 45.0))
    all_right = min(right.values()) == 1.0
    triangle = np.nanmax(bound) > np.nanmin(bound) and bound[-1] >= bound[0]
    agree = "agrees" if all_right and triangle else "partly agrees"
    lines = [
        "## Fig. 4: rotation and translation discrepancy (eq. 80-81)",
        "",
        f"![Fig. 4]({figdir}/{FILES['fig4']})",
        "",
        "- Rotation discrepancy of the PPO pose, RMSE per cell: "
        f"median {np.nanmedian(rot):.3f} deg, largest {np.nanmax(rot):.3f} deg "
        f"(at alpha = {alphas[np.nanargmax(rot) // rot.shape[1]]:.3g}, "
        f"noise = {noises[np.nanargmax(rot) % rot.shape[1]]:.2f} px).",
        "- Right rotation candidate picked (the one of the two rotations of `Q` closer to the "
        "truth), "
        "over all problems of the grid: PPO "
        + ", ".join(f"{_pct(v)} at d = {d:g} m" for d, v in right.items())
        + "; `cv2.recoverPose` "
        + ", ".join(f"{_pct(v)} at d = {d:g} m" for d, v in right_cv.items())
        + ".",
        f"- Translation discrepancy above 45 deg in {_pct(bad_cells)} of the cells. The smallest "
        f"parallax factor from which the translation RMSE stays below 45 deg rises from "
        f"{bound[0]:.3g} at {noises[0]:.1f} px to {bound[-1]:.3g} at {noises[-1]:.1f} px noise.",
        "",
        f"**Verdict: {agree} with the paper.** The paper finds the rotation always identified and "
        "accurate down to alpha -> 0 (Proposition 7) and the translation discrepancy reaching "
        "90 deg in the lower-right triangle (large noise, small parallax); the measured grid "
        "shows the same "
        + (
            "pattern."
            if agree == "agrees"
            else "trend for the translation, but "
            + (
                "the right rotation was not picked in every problem (rates above)."
                if not all_right
                else "the failure region is not a lower-right triangle here."
            )
        ),
        "",
    ]
    return lines


def _fig56(res: dict, figdir: str) -> list[str]:
    lines = [
        "## Fig. 5 and 6: translation discrepancy, traditional cheirality minus PPO (eq. 82)",
        "",
        f"![Fig. 5]({figdir}/{FILES['fig5']})",
        "",
        f"![Fig. 6]({figdir}/{FILES['fig6']})",
        "",
        "Both methods choose among the same four candidates of the same `Q`, so the difference "
        "comes only from which candidate they pick. Two traditional methods are measured: "
        "`cv2.recoverPose` as users call it (it drops points farther than `distanceThresh = 50` "
        "baselines before counting) and the plain positive-depth test (the same call with "
        "`distanceThresh = 1e12`), which is the method the paper compares with.",
        "",
        "| depth | traditional | mean difference (deg) | cells > +0.5 deg | cells < -0.5 deg "
        "| min / max (deg) |",
        "|---:|---|---:|---:|---:|---:|",
    ]
    verdicts = []
    for d in res["depths"]:
        for key, name in (
            ("fig5_diff_cv", "cv2.recoverPose"),
            ("fig5_diff_cheir", "no distance cut"),
        ):
            g = _a(res, f"{key}_d{d:g}")
            pos, neg = float(np.mean(g > 0.5)), float(np.mean(g < -0.5))
            lines.append(
                f"| {d:g} m | {name} | {np.nanmean(g):+.2f} | {_pct(pos)} | {_pct(neg)} | "
                f"{np.nanmin(g):+.1f} / {np.nanmax(g):+.1f} |"
            )
            verdicts.append((d, name, float(np.nanmean(g)), pos, neg))
    noises = _a(res, "noises")
    noisy = noises >= 1.0
    cv_noisy = {
        d: float(np.nanmean(_a(res, f"fig5_diff_cv_d{d:g}")[:, noisy])) for d in res["depths"]
    }
    cv_neg = max(v[4] for v in verdicts if v[1] == "cv2.recoverPose")
    ch_mean = max(abs(v[2]) for v in verdicts if v[1] != "cv2.recoverPose")
    right_cv = min(res[f"rot_right_cv_d{d:g}"] for d in res["depths"])
    g30 = _a(res, "fig5_diff_cv_d30")
    mostly_positive = cv_neg <= 0.1 and all(v[2] > 0 for v in verdicts)
    lines += [
        "",
        "**Verdict: " + ("agrees" if mostly_positive else "partly agrees") + " with the paper.** "
        f"Against `cv2.recoverPose` PPO wins by up to {np.nanmax(g30):+.1f} deg (d = 30 m) where "
        "the whole scene lies beyond 50 baselines (small alpha, low noise): OpenCV's distance "
        "cut then leaves no point to count for any candidate and its choice is arbitrary (it "
        f"picked the right rotation in only {_pct(right_cv)} of the problems at the worst depth, "
        "PPO in all of them). "
        + (
            ""
            if mostly_positive
            else "It is not ahead everywhere: over the cells with noise >= 1 px "
            "`cv2.recoverPose` is "
            "better on average by "
            + ", ".join(f"{-cv_noisy[d]:.2f} deg at d = {d:g} m" for d in res["depths"])
            + f" (up to {_pct(cv_neg)} of the cells below -0.5 deg). There the distance cut keeps "
            "only points with clear parallax in the vote, while the PPO count gives every point "
            "the same weight, including those whose m2 sign is set by the noise. "
        )
        + "Against the plain positive-depth test, the paper's traditional method, the mean "
        f"difference is within {ch_mean:.2f} deg at every depth and of both signs: on "
        "outlier-free points the two tests pick the same candidate in almost every problem, so "
        "the paper's margin (Fig. 5 and 6 'almost all above zero', growing with the noise) is "
        "not reproduced; the methods are equivalent in accuracy there, and PPO is the cheaper "
        "one (Fig. 13).",
        "",
    ]
    return lines


def _table3(res: dict) -> list[str]:
    t3 = res["table3"]
    lines = [
        "## Table III: the four candidate poses of a pure rotation",
        "",
        "True pose: Euler angles (x, y, z) = "
        f"{tuple(round(v, 3) for v in t3['true_euler_deg'])} deg, "
        f"t = 0; 50 points of the protocol's scene, noise {t3['noise_px']:g} px, `Q` the linear "
        "solution of eq. 42.",
        "",
        "| candidate | Euler angles (deg) | t | chosen by PPO |",
        "|---|---|---|:---:|",
    ]
    names = ("R1, +t", "R2, +t", "R1, -t", "R2, -t")
    for name, row in zip(names, t3["candidates"], strict=True):
        e = ", ".join(f"{v:.3f}" for v in row["euler_deg"])
        t = ", ".join(f"{v:.3f}" for v in row["t"])
        lines.append(f"| {name} | ({e}) | ({t}) | {'yes' if row['chosen'] else ''} |")
    chosen = [r for r in t3["candidates"] if r["chosen"]][0]
    err = float(np.max(np.abs(np.asarray(chosen["euler_deg"]) - t3["true_euler_deg"])))
    ok = err < 1e-6 and t3["pure_rotation"]
    lines += [
        "",
        f"PPO picks the rotation with Euler angles off by at most {err:.1e} deg, reports "
        f"PRI = {t3['pri']:.2e} (pure rotation: {t3['pure_rotation']}) and M3 = {t3['m3']:.2e}; "
        "`cv2.recoverPose` returns Euler angles ("
        + ", ".join(f"{v:.3f}" for v in t3["opencv_euler_deg"])
        + ").",
        "",
        "**Verdict: " + ("agrees" if ok else "differs") + " with the paper.** As in its Table III, "
        "two candidates carry the true rotation and two a rotation about 180 deg away, and the "
        "translation axis is meaningless (the paper's (0.973, 0.154, -0.174) is equally arbitrary: "
        "any `Q = R [a]x` solves eq. 42 when t = 0, so the axis depends on the points and the "
        "solver).",
        "",
    ]
    return lines


def _fig7(res: dict, figdir: str) -> list[str]:
    r, rm = _a(res, "fig7_ratio_rmse"), _a(res, "fig7_ratio_median")
    alphas, noises = _a(res, "alphas"), _a(res, "noises")
    top = r[-1]
    hard = (alphas[:, None] <= 0.03) & (noises[None, :] >= 2.5)
    easy = np.broadcast_to(alphas[:, None] >= 0.3, r.shape)
    agree = np.nanmedian(r[hard]) < 0.8 and abs(np.nanmedian(r[easy]) - 1.0) < 0.1
    lines = [
        "## Fig. 7: 3D error ratio, analytic reconstruction over DLT triangulation (eq. 83)",
        "",
        f"![Fig. 7]({figdir}/{FILES['fig7']})",
        "",
        "Both reconstructions use the PPO pose and are scaled by the true baseline; the error is "
        "the RMSE of the 3D points of all problems of a cell (the paper's ratio), with the ratio "
        "of median point errors beside it because single DLT points near infinity dominate an "
        "RMSE. "
        "The analytic points are `ppo_cv.ppo.analytic_points`: the two depths of eq. 36 combined "
        "with inverse-square-depth weights (the paper averages them).",
        "",
        f"- Large parallax (alpha >= 0.3): median RMSE ratio {np.nanmedian(r[easy]):.3f} "
        f"(median-error ratio {np.nanmedian(rm[easy]):.3f}); at alpha = 1 the ratio spans "
        f"{np.nanmin(top):.3f} ... {np.nanmax(top):.3f}.",
        f"- Small parallax and large noise (alpha <= 0.03, noise >= 2.5 px): median RMSE ratio "
        f"{np.nanmedian(r[hard]):.3f} (median-error ratio {np.nanmedian(rm[hard]):.3f}).",
        f"- Ratio below 1 in {_pct(float(np.mean(r < 1)))} of the cells; smallest "
        f"{np.nanmin(r):.3g}, largest {np.nanmax(r):.4f}. The gap between the RMSE ratio and "
        "the median-error ratio in the hard corner shows where the gain comes from: DLT throws "
        "a few nearly parallel rays far away, the analytic depths stay bounded.",
        "",
        f"**Verdict: {'agrees' if agree else 'partly agrees'} with the paper**, which finds the "
        "two methods equal at large parallax and the analytic points much better (ratio << 1) "
        "at small parallax and large noise."
        + (
            ""
            if agree
            else " The measured ratios are listed above; where they depart from the "
            "paper's picture it is because the error there is dominated by the wrong translation "
            "direction shared by both reconstructions, not by the triangulation method."
        ),
        "",
    ]
    return lines


def _fig11(res: dict, figdir: str) -> list[str]:
    t = _a(res, "fig4_t_rmse")
    pri, m3 = _a(res, "fig11_pri"), _a(res, "fig11_m3")
    lines = [
        "## Fig. 11: PRI and M3, and how they separate the ~90 deg translation failures",
        "",
        f"![Fig. 11]({figdir}/{FILES['fig11']})",
        "",
        "Magenta: the PRI = 0.015 contour; white dashes: translation RMSE = 45 deg (Fig. 4(b)). "
        "Rank correlation over the cells with the translation RMSE: "
        f"PRI {_rank_corr(pri, t):+.3f}, "
        f"M3 {_rank_corr(m3, t):+.3f}.",
        "",
        f"Per problem, a translation failure is a discrepancy (eq. 81) above "
        f"{res['settings']['bad_t_deg']:g} deg; a problem is flagged when the indicator is below "
        "the threshold. AUC is the area under the ROC curve of that test (1 = perfect "
        "separation); the best threshold maximises true-positive minus false-positive rate.",
        "",
        "| depth | failures / problems | PRI AUC | best PRI threshold (TPR / FPR) "
        "| PRI < 0.015: TPR / FPR / precision | M3 AUC | best M3 threshold (TPR / FPR) |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    rows = []
    for d in res["depths"]:
        s = res[f"sep_d{d:g}"]
        p, m, at = s["pri"], s["m3"], s["pri_at_0.015"]
        rows.append(s)
        lines.append(
            f"| {d:g} m | {s['n_bad']} / {s['n_problems']} | {p['auc']:.3f} | "
            f"{p['best_threshold']:.4f} ({_pct(p['best_tpr'])} / {_pct(p['best_fpr'])}) | "
            f"{_pct(at['tpr'])} / {_pct(at['fpr'])} / {_pct(at['precision'])} | {m['auc']:.3f} | "
            f"{m['best_threshold']:.4f} ({_pct(m['best_tpr'])} / {_pct(m['best_fpr'])}) |"
        )
    pri_better = all(s["pri"]["auc"] > s["m3"]["auc"] for s in rows)
    thresholds = [s["pri"]["best_threshold"] for s in rows]
    m3_thresholds = [s["m3"]["best_threshold"] for s in rows]
    lines += [
        "",
        "**Verdict: "
        + ("agrees" if pri_better else "partly agrees")
        + " with the paper.** "
        + (
            "PRI separates the failures better than M3 at every depth (higher AUC), as the paper "
            "reports. "
            if pri_better
            else "PRI does not beat M3 at every depth (see the AUC columns). "
        )
        + f"At the paper's 0.015, PRI flags {_pct(min(s['pri_at_0.015']['tpr'] for s in rows))}"
        f" ... {_pct(max(s['pri_at_0.015']['tpr'] for s in rows))} of the failures with "
        f"{_pct(min(s['pri_at_0.015']['fpr'] for s in rows))} ... "
        f"{_pct(max(s['pri_at_0.015']['fpr'] for s in rows))} false alarms: a cautious "
        "threshold. The best-separating PRI threshold is lower here, "
        f"{min(thresholds):.4f} ... {max(thresholds):.4f}, and falls with the depth, so the "
        "paper's claim that one threshold serves all three depths holds for catching failures "
        "but not for the false-alarm rate. M3 (best thresholds "
        f"{min(m3_thresholds):.4f} ... {max(m3_thresholds):.4f}) separates less well: it "
        "measures the whole angle between the rays, including the part of the noise across the "
        "epipolar lines, while m2 measures the angles to the translation only.",
        "",
    ]
    return lines


def _fig13(res: dict, figdir: str) -> list[str]:
    sizes = res["fig13_sizes"]
    sec = {k: np.asarray(v) for k, v in res["fig13_seconds"].items()}
    names = list(sec)
    lines = [
        "## Fig. 13: identification time over the number of points",
        "",
        f"![Fig. 13]({figdir}/{FILES['fig13']})",
        "",
        "Median over "
        f"{res['settings']['timing_runs']} Monte-Carlo runs of the time per call (each the "
        "fastest of three timing loops), same `Q` and points for all methods, one thread.",
        "",
        "| N | " + " | ".join(names) + " | cv2 / Method I | numpy DLT / Method I |",
        "|---:|" + "---:|" * (len(names) + 2),
    ]
    for i, n in enumerate(sizes):
        cells = [f"{sec[k][i] * 1e3:.3f} ms" for k in names]
        lines.append(
            f"| {n} | "
            + " | ".join(cells)
            + f" | {sec[names[3]][i] / sec[names[0]][i]:.1f}x"
            + f" | {sec[names[2]][i] / sec[names[0]][i]:.1f}x |"
        )
    r_np = sec[names[2]] / sec[names[0]]
    r_cv = sec[names[3]] / sec[names[0]]
    r_m2 = sec[names[1]] / sec[names[0]]
    lines += [
        "",
        "**Verdict: "
        + (
            "agrees with the paper on the direction, not on the size.**"
            if r_np.max() >= 7
            else "differs from the paper.**"
        )
        + " Like for like (numpy against numpy), cheirality "
        f"by DLT costs {r_np[0]:.0f}x Method I at N = {sizes[0]} and {r_np[-1]:.0f}x at "
        f"N = {sizes[-1]}; the paper reports 7-9x. The ratio grows with N because the DLT "
        "solves a 4x4 SVD per point and candidate while the PPO scores are a few vector "
        "operations per point. Against OpenCV's C++ `recoverPose` the ratio is "
        f"{r_cv.min():.1f}x ... {r_cv.max():.1f}x"
        + (
            ", below 1 at the smallest N, where the fixed cost of a numpy call outweighs the "
            "per-point work"
            if r_cv.min() < 1
            else ""
        )
        + f". Method II costs {r_m2.min():.1f}x ... {r_m2.max():.1f}x Method I"
        + (
            " (the paper finds them almost equal)."
            if r_m2.max() < 1.5
            else "; the paper finds them almost equal, here the analytic points add measurably "
            "to a "
            "selection that is itself only a few vector operations."
        ),
        "",
    ]
    return lines


def render(res: dict, figdir: str) -> str:
    s = res["settings"]
    head = [
        "# Reproduction of the paper's simulation results",
        "",
        "Cai et al., *Equivalent Constraints for Two-View Geometry*, Section 5, recomputed with "
        "ppo_cv. Regenerate every number and figure of this page with",
        "",
        "```",
        s["command"].strip(),
        "```",
        "",
        f"Protocol (`ppo_cv.data_gen.paper_protocol`): K = [[800, 0, 512], [0, 800, 512], "
        f"[0, 0, 1]], {s['points']} points in U((0, 0, d), (30, 30, d)), Euler angles "
        "N(0, diag(5^2, 5^2, 20^2)) deg, translation in the OXY plane with length alpha * 4.2 m, "
        f"d = 30 m unless stated. Grid: {s['grid']} parallax factors on a log grid from 1e-3 to 1 "
        f"x {s['grid']} noise levels from 0.1 to 5 px (paper: 200 noise levels); {s['poses']} "
        f"poses x {s['runs']} Monte-Carlo runs per cell (paper: 200 x 30). Each problem is "
        "solved from the linear least-squares `Q` of its 50 points (eq. 42). The run took "
        f"{s['total_seconds']:.0f} s with {s['jobs']} processes (Python {s['versions']['python']}, "
        f"numpy {s['versions']['numpy']}, OpenCV {s['versions']['opencv']}); all plotted values "
        "are in `results.json` next to the figures.",
        "",
    ]
    body = _fig4(res, figdir) + _fig56(res, figdir) + _table3(res) + _fig7(res, figdir)
    body += _fig11(res, figdir) + _fig13(res, figdir)
    return "\n".join(head + body)
