"""The figures of ``prbdm report`` (PNG bytes, matplotlib with the Agg backend) from
:func:`prbdm.report.measure.run_report`'s numbers."""
from __future__ import annotations

import io
import math

from .measure import PANEL_TRUTHS


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return buf.getvalue()


_MARKERS = {"plate_truth": "s", "beam_truth": "D", "rfe": "v", "howell-1r": "<", "su-3r": ">",
            "fit_plate": "P", "network": "*", "refined": "X", "direct": "h",
            "plate_network": "p", "plate_refined": "d", "plate_direct": "H",
            "mindlin_truth": "8", "fit_mindlin": "^", "mindlin_network": "x",
            "mindlin_refined": "+", "mindlin_direct": "1"}
_PANEL_FITS = tuple(f"fit_{t}" for t in PANEL_TRUTHS)   # to a panel truth, not start counts


def _colors(methods, plt) -> dict:
    """Distinct colours; the fits at several start counts in shades of one hue."""
    fits = [m["key"] for m in methods
            if m["key"].startswith("fit_") and m["key"] not in _PANEL_FITS]
    greens = plt.get_cmap("Greens")
    out = {k: greens(0.4 + 0.55 * i / max(len(fits) - 1, 1)) for i, k in enumerate(fits)}
    others = [m["key"] for m in methods if m["key"] not in out]
    tab = plt.get_cmap("tab10")
    palette = [tab(i) for i in (0, 1, 3, 4, 5, 6, 7, 8, 9, 2)]
    if len(others) > len(palette):        # rows after the tenth: the lighter tab20 shades
        light = plt.get_cmap("tab20")
        palette += [light(2 * i + 1) for i in (0, 1, 3, 4, 5, 6, 7, 8, 9, 2)]
    out.update({k: palette[i % len(palette)] for i, k in enumerate(others)})
    return out


def plot_error_vs_time(res: dict) -> bytes:
    plt = _pyplot()
    refs = [ref for ref in ("plate", "mindlin", "beam")
            if any(m["errors"].get(ref, {}).get("reference") for m in res["methods"])]
    fig, axes = plt.subplots(len(refs), 2, figsize=(12, 4.5 * len(refs)), squeeze=False)
    colors = _colors(res["methods"], plt)
    for row, ref in enumerate(refs):
        for col, (stat, label) in enumerate((("loss", "loss (docs/conventions.md §3) [%]"),
                                             ("worst", "worst per-mode frequency error [%]"))):
            ax = axes[row, col]
            for m in res["methods"]:
                e = m["errors"][ref]
                color = colors[m["key"]]
                if e.get("reference"):
                    ax.axvline(m["time_s"], color=color, ls="--", lw=1,
                               label=f"{m['label']} (reference)")
                    continue
                scale = 1.0 if stat == "loss" else 100.0
                med, p95 = e[f"{stat}_median"] * scale, e[f"{stat}_p95"] * scale
                if not (math.isfinite(med) and med > 0):
                    continue
                mk = _MARKERS.get(m["key"], "o")
                ax.errorbar([m["time_s"]], [med], yerr=[[0], [max(p95 - med, 0)]], fmt=mk,
                            color=color, ms=8, capsize=3, label=m["label"])
                if m["total_s"] > m["time_s"] * 1.01:
                    ax.plot([m["time_s"], m["total_s"]], [med, med], color=color, lw=0.8,
                            ls=":")
                    ax.plot([m["total_s"]], [med], marker="|", color=color, ms=10)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            ax.set_xlabel("time per beam [s]")
            ax.set_ylabel(label)
            ax.set_title({"plate": "against the Kirchhoff plate truth (reference)",
                          "mindlin": "against the Mindlin plate truth (thick panels' physics)",
                          "beam": "against the beam truth"}[ref])
    handles = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab.replace(" (reference)", ""), h)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=4, fontsize=8,
               frameon=False)
    fig.suptitle("Error against time per beam: marker = median, whisker up to the 95th "
                 "percentile; dotted line to '|' = with the truth the method needs", fontsize=10)
    fig.tight_layout(rect=(0, 0.1, 1, 0.97))
    return _png(fig)


def plot_scaling(res: dict) -> dict:
    plt = _pyplot()
    sc = res["scaling"]
    out = {}
    fig, ax = plt.subplots(figsize=(6, 4.2))
    rows = sc["fit_vs_n"]["rows"]
    ax.loglog([r["n"] for r in rows], [r["time_s"] for r in rows], "o-")
    ax.set_xlabel("joints n (modes mapped = n)")
    ax.set_ylabel("fit time per beam [s]")
    ax.set_title(f"fit time against n ({sc['fit_vs_n']['starts']} starts, {sc['beams']} beams)")
    ax.set_xticks([r["n"] for r in rows])
    ax.set_xticklabels([str(r["n"]) for r in rows])
    ax.grid(True, which="both", alpha=0.3)
    out["fit_time_vs_n.png"] = _png(fig)

    fig, ax = plt.subplots(figsize=(6, 4.2))
    rows = sc["fit_vs_starts"]["rows"]
    ax.loglog([r["starts"] for r in rows], [r["time_s"] for r in rows], "o-", label="time")
    ax.set_xlabel("start points")
    ax.set_ylabel("fit time per beam [s]")
    ax2 = ax.twinx()
    ax2.semilogx([r["starts"] for r in rows], [r["loss_median"] for r in rows], "s--", color="C1",
                 label="median loss")
    ax2.set_ylabel("median loss [%]", color="C1")
    ax.set_title(f"fit time against starts (n = 4, {sc['beams']} beams)")
    ax.grid(True, which="both", alpha=0.3)
    out["fit_time_vs_starts.png"] = _png(fig)

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for model, mk in (("beam", "o-"), ("plate", "s-")):
        rows = [r for r in sc["truth_vs_mesh"]["rows"] if r["model"] == model]
        if rows:
            ax.loglog([r["elements"] for r in rows], [r["time_s"] for r in rows], mk,
                      label=f"{model} truth")
    ax.set_xlabel("elements (beam: Hermite elements; plate: Argyris triangles, half model)")
    ax.set_ylabel("time per beam [s]")
    ax.set_title("truth time against mesh size")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    out["truth_time_vs_mesh.png"] = _png(fig)

    fig, ax = plt.subplots(figsize=(6, 4.2))
    rows = sc["network_throughput"]["rows"]
    ax.loglog([r["batch"] for r in rows], [r["beams_per_s"] for r in rows], "o-")
    ax.set_xlabel("batch size [beams]")
    ax.set_ylabel("beams per second")
    ax.set_title("network throughput against batch size")
    ax.grid(True, which="both", alpha=0.3)
    out["network_throughput.png"] = _png(fig)
    return out
