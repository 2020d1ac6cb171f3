"""The Markdown of ``prbdm report``: the method tables and ``report.md`` from
:func:`prbdm.report.measure.run_report`'s numbers."""
from __future__ import annotations

import math

from .measure import MODES


def _fmt_t(s):
    if s is None or not math.isfinite(s):
        return ""
    if s < 1e-3:
        return f"{s * 1e6:.3g} µs"
    if s < 1:
        return f"{s * 1e3:.3g} ms"
    return f"{s:.3g} s"


def _fmt_int(v):
    return "" if v is None else f"{v:.0f}"


def _fmt_p(v, pct=True):
    if v is None or not math.isfinite(v):
        return ""
    return f"{v * 100:.3g} %" if pct else f"{v:.3g} %"


def method_table(res: dict, ref: str) -> str:
    hdr = ("| method | n | modes | loss median | loss p95 | worst freq. error median | p95 | "
           "time per beam | from geometry | one beam at a time |")
    lines = [hdr, "|" + "---|" * 10]
    for m in res["methods"]:
        e = m["errors"][ref]
        n = "" if m["joints"] is None else str(m["joints"])
        if e.get("reference"):
            lines.append(f"| **{m['label']}** (reference) | | | 0 | 0 | 0 | 0 | "
                         f"{_fmt_t(m['time_s'])} | {_fmt_t(m['total_s'])} | |")
            continue
        lines.append(
            f"| {m['label']} | {n} | {e['modes']} | {_fmt_p(e['loss_median'], False)} | "
            f"{_fmt_p(e['loss_p95'], False)} | {_fmt_p(e['worst_median'])} | "
            f"{_fmt_p(e['worst_p95'])} | {_fmt_t(m['time_s'])} | {_fmt_t(m['total_s'])} | "
            f"{_fmt_t(m.get('single_s'))} |")
    return "\n".join(lines)


def per_mode_table(res: dict, ref: str) -> str:
    lines = ["| method | " + " | ".join(f"mode {j + 1}" for j in range(MODES)) + " |",
             "|---|" + "---|" * MODES]
    for m in res["methods"]:
        e = m["errors"][ref]
        if e.get("reference"):
            continue
        vals = [_fmt_p(v) for v in e["per_mode_median"]] + [""] * (MODES - e["modes"])
        lines.append(f"| {m['label']} | " + " | ".join(vals) + " |")
    return "\n".join(lines)


def _mindlin_section(res: dict) -> list:
    """The Markdown lines against the Mindlin plate; none for a report made before it had one."""
    truth = next((m for m in res["methods"] if m["key"] == "mindlin_truth"), None)
    if truth is None:
        return []
    n = next(m for m in res["methods"] if m["key"] == "beam_truth")["errors"]["mindlin"]
    has_net = any(m["key"] == "mindlin_network" for m in res["methods"])
    return [
        "## Against the Mindlin plate truth (the physics of thick or necked panels)",
        "",
        f"Every model against the shear-deformable plate's frequencies ({n.get('beams', 0)} "
        f"beams; {len(res.get('mindlin_failures', []))} where it could not be solved are left "
        "out): the truth `--truth auto` takes for a panel thick or necked enough that the "
        "Kirchhoff plate would be more than 1 % high (docs/howto/choose-a-truth.md). `fit to Mindlin truth` "
        "was fitted to it, and the Mindlin network's rows "
        + ("(trained on it) are there too." if has_net
           else "are absent: no Mindlin network was found."),
        "",
        method_table(res, "mindlin"),
        "",
        "Median per-mode frequency error (worst over the poses) against the Mindlin plate:",
        "",
        per_mode_table(res, "mindlin"),
        "",
    ]


def render_markdown(res: dict, stability_md: str | None = None, stability_note: str = "") -> str:
    c, env, ck, src = res["config"], res["environment"], res["checkpoint"], res["source"]
    sc = res["scaling"]
    n_plate = next(m for m in res["methods"] if m["key"] == "beam_truth")["errors"]["plate"]
    lines = [
        "# Error against run time",
        "",
        f"Made by `{c['command']}` on {env['date']}, prbdm commit `{env['git_commit']}`, "
        f"{res['elapsed_s']:.0f} s in all.",
        "",
        f"- **Held-out beams:** {c['beams']} beams, " + (
            f"`random_beam({src['seed']}, i)`, i = {src['indices']} (paper generator, p = 10); "
            f"the checkpoint was trained on seed {src.get('checkpoint_training_seed')}, so none "
            "of these beams was seen in training."
            if src["source"] == "generated" else
            f"from the data set `{src['path']}` (seed {src['seed']}), rule: {src['rule']}; "
            f"indices {src['indices'][:5]}{' ...' if len(src['indices']) > 5 else ''}."),
        f"- **Checkpoint:** `{ck['name']}` ({ck['training_mode']} mode, {ck['candidates']} "
        f"candidates), trained on {ck['dataset_size']} beams of seed {ck['dataset_seed']} "
        f"(dataset max_index {ck['dataset_max_index']}).",
        f"- **Model:** n = {c['joints']} joints, {c['modes']} modes, {_poses_words(c)}, "
        f"`{c['law']}` law; fits: "
        f"`fit_many(seed={c['fit_seed']})`, minimising the {c.get('objective', 'eigenvalue')} "
        f"objective; refinement {c['refine_iter']} iterations from the "
        f"network's candidates and the fit's four fixed starts.",
        f"- **Machine:** {env['cores']} cores ({env['system']} {env['machine']}), load average "
        f"{env['load_average_start']:.2f} at the start and {env['load_average_end']:.2f} at the "
        f"end (other jobs were running); torch on {env['torch_threads']} thread.",
        "- **Versions:** " + ", ".join(f"{k} {v}" for k, v in env["versions"].items()) + ".",
        f"- **Random draws:** held-out beams as above; fit start points seeded with "
        f"{c['fit_seed']}; network-throughput beams `{sc['network_throughput']['beams']}`.",
        "",
        "![error against time per beam](error_vs_time.png)",
        "",
        "## Against the plate truth (the reference)",
        "",
        f"Every model against the Kirchhoff plate's frequencies ({n_plate.get('beams', 0)} beams; "
        f"{len(res['plate_failures'])} where the plate could not be solved are left out). "
        "The fits, the network and the refinement were made for the *beam* truth; "
        "`fit to plate truth` was fitted to the plate itself, and the plate network's rows "
        + ("(trained on the plate truth) are there too." if any(
            m["key"] == "plate_network" for m in res["methods"])
           else "are absent: no plate network was found."),
        "",
        method_table(res, "plate"),
        "",
        "Median over the beams of each mode's frequency error (worst over the poses) against "
        "the plate truth:",
        "",
        per_mode_table(res, "plate"),
        "",
        *_mindlin_section(res),
        "## Against the beam truth (what the fits and the network target)",
        "",
        method_table(res, "beam"),
        "",
        "Median per-mode frequency error (worst over the poses) against the beam truth:",
        "",
        per_mode_table(res, "beam"),
        "",
        "Columns: `modes` — how many modes the error compares (`min(n, 4)`; the classical "
        "models have only 1 or 3); `loss` — docs/conventions.md §3, mean over the model's poses of "
        "`||lambda[:r] - lambda_ref[:r]|| / ||lambda_ref[:r]||`, in %; `worst freq. error` — the "
        "largest `|omega / omega_ref - 1|` over those modes and poses, per beam; median and 95th "
        "percentile over the beams. `time per beam` — wall time of the method alone, mean per "
        "beam; batched methods (RFE chain, classical models, fits, network, refinement) are "
        "timed on all beams in one call and divided by their number (the cheap ones best of 3); "
        "truths are solved one beam at a time. `from geometry` adds the mean time of the truth "
        "the method needs (beam truth for fits and refinement, a plate truth for the fits and "
        "refinements to it). "
        f"`one beam at a time` — the same method called for each of the first {c['single']} "
        "beams alone (what `prbdm fit`/`predict` cost), mean.",
        "",
        "Classical PRBMs: cut from the real planform like any prbdm chain (exact link masses and "
        "inertias), with their own springs `K_j = c_j EI / L` where, on a tapered beam, EI is "
        "the tip-load equivalent `L^3 / (3 ∫ (L-x)^2 / EI(x) dx)` (the uniform beam with the same "
        "tip-force compliance; `prbdm/classical.py`), evaluated at the paper poses of their own "
        "n (30 poses for n = 1, 9 for n = 3).",
        "",
        "## How the cost grows",
        "",
        f"Scaling studies on the first {sc['beams']} held-out beams (fits batched over them, "
        "time per beam).",
        "",
        "![fit time against n](fit_time_vs_n.png) ![fit time against starts](fit_time_vs_starts.png)",
        "",
        "![truth time against mesh size](truth_time_vs_mesh.png) "
        "![network throughput](network_throughput.png)",
        "",
        f"Fit time against n ({sc['fit_vs_n']['starts']} starts, modes mapped = n, paper poses):",
        "",
        "| n | poses | time per beam | median loss |",
        "|---|---|---|---|",
        *[f"| {r['n']} | {r['poses']} | {_fmt_t(r['time_s'])} | {r['loss_median']:.3g} % |"
          for r in sc["fit_vs_n"]["rows"]],
        "",
        "Fit time against starts (n = 4, 4 modes):",
        "",
        "| starts | time per beam | median loss |",
        "|---|---|---|",
        *[f"| {r['starts']} | {_fmt_t(r['time_s'])} | {r['loss_median']:.4g} % |"
          for r in sc["fit_vs_starts"]["rows"]],
        "",
        "Truth time against mesh size (median over the beams; `elements` option → actual "
        "elements):",
        "",
        "| truth | `elements` | elements (triangles) | DOFs | time per beam |",
        "|---|---|---|---|---|",
        *[f"| {r['model']} | {r['elements_option']} | {r['elements']:.0f} | "
          f"{_fmt_int(r['dofs'])} | {_fmt_t(r['time_s'])} |"
          for r in sc["truth_vs_mesh"]["rows"]],
        "",
        "Network throughput (`Surrogate.predict` on Beam objects: features, network, candidate "
        "choice, k, PRBDM frequencies at every pose, truth frequencies; best of several):",
        "",
        "| batch | beams/s |",
        "|---|---|",
        *[f"| {r['batch']} | {r['beams_per_s']:.4g} |" for r in sc["network_throughput"]["rows"]],
    ]
    for key, name in (("plate_failures", "Plate"), ("mindlin_failures", "Mindlin plate")):
        if res.get(key):
            lines += ["", f"{name} truth failures: " + "; ".join(
                f"beam {f['beam']}: {f['error']}" for f in res[key])]
    # the stability suite's Markdown brings its own heading
    if not (stability_md or "").lstrip().startswith("#"):
        lines += ["", "## Stability on stiff and extreme cases"]
    lines += ["", stability_md if stability_md else stability_note]
    return "\n".join(lines) + "\n"


def _poses_words(c: dict) -> str:
    """The poses the report's models are measured at, by the checkpoint's pose target."""
    if c.get("pose_target") == "shape":
        return ("at rest (the straight pose; the shape pose target: a network trained there "
                "and fits made there, their stiffness held at deflected poses)")
    return f"paper poses ({', '.join(f'{p:.2f}' for p in c['poses'])} rad)"

