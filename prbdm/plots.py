"""Plots a mechanical engineer wants to see (matplotlib, imported only here, Agg backend).

``plot_fit``: the paper's Figs. 7-12 in one figure: the planform cut into its rigid links with
their properties, and the stiffness correction factor against the joint deflection angle (right
axis: change from the mean, Eq. 24).
"""
from __future__ import annotations

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_fit(beam, result, path) -> None:
    """Planform with links and joints, link table, and SCF vs deflection angle, saved to path."""
    import torch

    from .model import BeamTensors, links_from_gamma

    plt = _pyplot()
    bt = BeamTensors.from_beams(beam)
    with torch.no_grad():
        links = {k: v.numpy() for k, v in
                 links_from_gamma(bt, torch.as_tensor(result.gamma)).physical(bt).items()}
    L = beam.length
    cuts = np.concatenate([[0.0], links["joint_x"], [L]])
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 8), gridspec_kw={"height_ratios": [3, 2]})
    colors = plt.cm.tab10(np.arange(len(cuts) - 1) % 10)
    for j in range(len(cuts) - 1):
        xs = np.linspace(cuts[j], cuts[j + 1], 50)
        w = np.interp(xs, beam.x, beam.half_width)
        ax.fill_between(xs, -w, w, color=colors[j], alpha=0.45 if j else 0.2, lw=0)
        label = "link 0 (clamped)" if j == 0 else (
            f"link {j}\nm={links['mass'][j - 1]:.3g} kg\nJ={links['inertia'][j - 1]:.3g} kg m²")
        ax.text((cuts[j] + cuts[j + 1]) / 2, -1.15 * beam.half_width.max(), label,
                ha="center", va="top", fontsize=7)
        if j:
            xc = cuts[j] + links["com"][j - 1]
            ax.plot(xc, 0, "k+", ms=8)
    ax.plot(beam.x, beam.half_width, "k-", lw=1)
    ax.plot(beam.x, -beam.half_width, "k-", lw=1)
    for xj in links["joint_x"]:
        ax.axvline(xj, color="k", ls="--", lw=0.8)
        ax.plot(xj, 0, "ko", ms=5)
    ax.axvline(0, color="k", lw=3)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_ylim(-2.2 * beam.half_width.max(), 1.3 * beam.half_width.max())
    ax.set_title(f"{result.joints}R-PRBDM, law '{result.law}': gamma = "
                 + ", ".join(f"{g:.3f}" for g in result.gamma)
                 + f"\nloss {result.loss_percent:.4g} %  (o joint, + centre of mass)", fontsize=9)
    angles = np.degrees(np.asarray(result.poses)[:, 0])
    k = np.asarray(result.k)
    ax2.plot(angles, k, "o-", color="C0")
    ax2.set_xlabel("joint deflection angle theta [deg]")
    ax2.set_ylabel("stiffness correction factor k")
    ax2.grid(True, alpha=0.3)
    right = ax2.twinx()
    mean = k.mean()
    right.set_ylim(*((np.array(ax2.get_ylim()) - mean) / mean * 100))
    right.set_ylabel("change from mean [%] (Eq. 24)")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
