"""The stability suite on stiff and extreme cases (issue 7), as data: ``CASES``.

Every case builds a panel or a model at an extreme of the input range, runs the truth, the PRBDM,
its gradients, a fit or the network on it, and checks the outcome against an *independent*
reference: the analytic Euler-Bernoulli cantilever, the mesh-free shooting solution of the
variable-width beam ODE, exact scaling laws (omega scales with ``sqrt(E t^2 / (rho L^4))``), the
rigid-finite-element limit (second-order convergence to the beam), a closed-form 2R model,
finite differences, float64 against float32. A case passes when every number is finite, sorted
and positive, gradients are finite, and each accuracy lies within its stated tolerance -- or
when the input is refused with a :class:`prbdm.errors.BadInput` naming the field. Never a silent
wrong number.

    rows = run_suite(quick=True)        # one dict per case (stability_checks.run_case)

``tests/test_stability.py`` runs each case as a pytest case (``quick=False`` ones under
``-m slow``); :mod:`prbdm.report.stability` writes the table of docs/stability.md (``prbdm
report`` appends it; ``python benchmarks/stability.py`` prints it).
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from prbdm.errors import BadInput
from prbdm.geometry import Beam, Material, random_beam

from .stability_checks import (
    ALUMINIUM,
    ELASTOMER,
    EPS32,
    GAMMA4,
    RFE_BOUND,
    STEEL,
    TITANIUM,
    Case,
    Row,
    analytic_omega,
    beam_truth,
    is_sane,
    prbdm_lam,
    refused,
    rel_err,
    rfe_omega,
    run_case,
    shooting_error,
    tapered_panel,
    torch1,
    uniform_panel,
)


def case_scaling(row: Row, beam: Beam, ref: Beam, analytic: bool):
    """Size, thickness and material enter only through lambda_0 = E t^2 / (rho L^4): the
    nondimensional eigenvalues of a shape must not change, and the SI ones must scale exactly."""
    torch = torch1()
    from prbdm import model
    lam = prbdm_lam(row, beam, GAMMA4)
    lam_ref = prbdm_lam(Row(), ref, GAMMA4, grad=False)
    row.check("PRBDM finite, sorted, positive (paper poses)", None, ok=is_sane(lam))
    row.check("PRBDM nondim. eigenvalues = reference panel's", rel_err(lam, lam_ref), 1e-10,
              key=True)
    g = torch.tensor(GAMMA4, dtype=torch.float64)
    si = model.eigenvalues(beam, g).numpy()
    si_ref = model.eigenvalues(ref, g).numpy()
    l0 = [float(model.BeamTensors.from_beams(b).lambda0) for b in (beam, ref)]
    row.check("SI eigenvalues scale by E t^2/(rho L^4)", rel_err(si / l0[0], si_ref / l0[1]), 1e-10)
    om = beam_truth(row, beam)
    om_ref = beam_truth(Row(), ref)
    row.check("beam truth nondim. = reference panel's", rel_err(om, om_ref), 1e-10)
    if analytic:
        row.check("beam truth vs cos a cosh a = -1 (5 modes)", rel_err(om, analytic_omega(5)), 1e-4)
        n = 20
        e = np.abs(rfe_omega(row, beam, n, grad=True)[:3] / analytic_omega(3) - 1) * n * n
        row.check("RFE n=20 vs analytic, n^2 err / bound (modes 1-3)",
                  float(np.max(e / RFE_BOUND)), 1.0)
    else:
        row.check("beam truth vs shooting (modes 1-2)", shooting_error(beam, om, 2), 1e-4)


def case_width(row: Row, beam: Beam, order: bool, shoot_modes: int, plate=None):
    """Fast width changes: truth against the mesh-free shooting solution, PRBDM against the beam
    (rigid-finite-element limit), widths scaled by 0.01 change nothing nondimensional. ``plate``:
    None, "finite", "slender" (also within 2 % of the beam) or "refused" (BadInput expected)."""
    from prbdm.truth.analytic import beam_omega_scale
    om = beam_truth(row, beam)
    row.check("beam truth finite, sorted, positive", None, ok=is_sane(om))
    row.check(f"beam truth vs shooting (modes 1-{shoot_modes})",
              shooting_error(beam, om, shoot_modes), 1e-4, key=True)
    errs = {}
    for n in (20, 40):
        errs[n] = np.abs(rfe_omega(row, beam, n, grad=True)[:3] / om[:3] - 1)
    row.check("RFE n=40 vs beam truth, n^2 rel. error (modes 1-3)", float(errs[40].max() * 1600), 1.5)
    if order:
        p = math.log2(errs[20][0] / errs[40][0])
        row.check("RFE observed order p, mode 1 (n 20 -> 40): abs(p - 2)", abs(p - 2), 0.2)
    lam = prbdm_lam(row, beam, GAMMA4)
    small = Beam(x=beam.x, half_width=beam.half_width * 0.01, thickness=beam.thickness,
                 material=beam.material)
    row.check("PRBDM finite, sorted, positive (paper poses)", None, ok=is_sane(lam))
    row.check("PRBDM nondim. unchanged by widths x 0.01",
              rel_err(prbdm_lam(Row(), small, GAMMA4, grad=False), lam), 1e-10)
    if plate:
        from prbdm.truth import bending_frequencies
        try:
            res = bending_frequencies(beam, model="plate", modes=4)
        except BadInput as exc:
            row.check("plate truth refused: BadInput naming half_width", None,
                      ok=plate == "refused" and "half_width" in str(exc))
            row.note = f"plate: {exc}"
        else:
            ratio = res.omega / (om[:4] * beam_omega_scale(beam))
            row.check("plate truth finite, sorted, positive", None,
                      ok=is_sane(res.omega) and plate != "refused")
            if plate == "slender":
                # a narrow plate tends to the Euler-Bernoulli beam (+0.6 % at L/b = 10)
                row.check("plate / beam - 1 (slender limit, modes 1-4)",
                          float(np.abs(ratio - 1).max()), 0.02)
            row.note = "plate / beam, modes 1-4: " + ", ".join(f"{r:.4f}" for r in ratio)


def case_needle_beyond(row: Row, tip: float):
    """Beyond the truth's 1e6 width ratio: the truth refuses naming half_width; the PRBDM
    answers up to 1e12 and refuses beyond (it would otherwise fail inside eigvalsh near 1e17)."""
    beam = Beam(x=[0.0, 1.0], half_width=[0.1, tip], thickness=0.02)
    from prbdm.truth import bending_frequencies
    ok, msg = refused(lambda: bending_frequencies(beam, model="beam"), "half_width")
    row.check("beam truth refuses (BadInput naming half_width)", None, ok=ok)
    if 0.1 / tip <= 1e12:
        lam = prbdm_lam(row, beam, GAMMA4)
        row.check("PRBDM finite, sorted, positive", None, ok=is_sane(lam))
        # the last joint's spring integrates dx / w up to the tip: for a linear taper that is
        # (b - a) log(w_a / w_tip) / (w_a - w_tip), exact in closed form however thin the tip
        torch = torch1()
        from prbdm import model
        bt = model.BeamTensors.from_beams(beam)
        links = model.links_from_gamma(bt, torch.tensor(GAMMA4, dtype=torch.float64))
        a = float(links.cuts[-2] + links.cuts[-3]) / 2                # centre of link n-1
        wa, wt = 0.1 + (tip - 0.1) * a, tip
        exact = (1 - a) * math.log(wa / wt) / (wa - wt)
        # rounding of the tip width itself (eps w_root / w_tip) bounds what any formula can do:
        # ~eps ratio / log(ratio) relative, 1e-6 at 1e11:1
        row.check("tip compliance int dx/w vs closed form", abs(
            float(links.tributary_compliance[-1]) / exact - 1), 1e-6, key=True)
        ref = prbdm_lam(Row(), Beam(x=[0.0, 1.0], half_width=[0.1, 1e-6], thickness=0.02), GAMMA4,
                     grad=False)
        msg = (f"lam_n / lam_n of the 1e5:1 needle = {lam[0, -1] / ref[0, -1]:.3f} (the tip "
               "compliance grows like log(1/w_tip)); the beam truth refuses it")
    else:
        ok, msg = refused(lambda: prbdm_lam(row, beam, GAMMA4), "half_width")
        row.check("PRBDM refuses (BadInput naming half_width)", None, ok=ok)
    row.note = msg[:160]


def case_joints(row: Row, n: int):
    """n joints: bounds feasible, paper poses inside n theta <= pi/2, RFE accuracy (exact
    spring-pendulum for n = 1), autograd against central differences."""
    torch = torch1()
    from prbdm import model
    from prbdm.fit import gamma_from_z
    beam = uniform_panel()
    row.check("gamma bounds feasible: (n+1) 0.025 <= 1", None, ok=(n + 1) * model.GAMMA_MIN <= 1)
    gen = torch.Generator().manual_seed(n)
    g = gamma_from_z(torch.randn(64, n + 1, generator=gen, dtype=torch.float64))
    row.check("gamma_from_z on the bounded simplex", float((g.sum(-1) - 1).abs().max()), 1e-14,
              ok=bool((g >= model.GAMMA_MIN - 1e-15).all() and (g <= model.GAMMA_MAX).all()
                      and (g.sum(-1) - 1).abs().max() < 1e-14))
    P = model.paper_poses(n)
    row.check("paper poses: n theta <= pi/2", float((n * P[:, 0]).max() - math.pi / 2), 1e-12)
    gam = g[0].numpy()
    lam = prbdm_lam(row, beam, gam, "paper")
    row.check("PRBDM finite, sorted, positive (paper poses)", None, ok=is_sane(lam))
    om = rfe_omega(row, beam, n)
    if n == 1:
        # m = 2w/2, c = 1/4, J = m/48, s = w/6 (nondimensional): lam = s / (m c^2 + J) = 2
        lam1 = prbdm_lam(Row(), beam, [0.5, 0.5], [0.0, 0.4, 1.2], grad=False)
        row.check("1R = spring-pendulum, lam = 2 at every pose", rel_err(lam1, 2.0), 1e-12,
                  key=True)
    else:
        r = min(3, n)
        e = np.abs(om[:r] / analytic_omega(r) - 1)
        row.check("RFE mode 1 vs analytic (bound 0.25/n^2)", float(e[0]), RFE_BOUND[0] / n ** 2,
                  key=True)
        if n >= 4:
            row.check("RFE modes 2-3 vs analytic, error / bound (0.85, 1.35)/n^2",
                      float(np.max(e[1:] * n * n / np.array(RFE_BOUND[1:]))), 1.0)
    # autograd against central differences along a random tangent direction of gamma
    bt = model.BeamTensors.from_beams(beam)
    x = torch.tensor(gam[:-1], dtype=torch.float64, requires_grad=True)
    v = torch.randn(n, generator=gen, dtype=torch.float64) * 0.01

    def f(gf):
        full = torch.cat([gf, 1 - gf.sum(-1, keepdim=True)])
        return model.eigenvalues_unit_k(bt, full, P).log().sum()

    (gr,) = torch.autograd.grad(f(x), x)
    # fourth-order stencil, steps ~1e-4 in gamma: for n = 39 the derivative is 1e-3 of |f|, and
    # a second-order stencil cannot get below 4e-6 between truncation and rounding
    h = 1e-2
    with torch.no_grad():
        fd = (8 * (f(x + h * v) - f(x - h * v)) - f(x + 2 * h * v) + f(x - 2 * h * v)) / (12 * h)
    ad = float(gr @ v)
    # relative to |grad| |v|: a random direction may be nearly orthogonal to the gradient
    scale = float(torch.linalg.vector_norm(gr) * torch.linalg.vector_norm(v))
    row.check("autograd vs finite differences (rel. to norm(grad) norm(v))", abs(ad - float(fd)) / scale,
              1e-6)


def _closed_form_2r(w, gamma, theta2):
    """Eigenvalues of a uniform 2R model written out by hand: m = 2 w l, c = l/2, J = m l^2/12;
    s_j = w / (6 span_j) over the tributary spans; M from the link-centre geometry."""
    from scipy.linalg import eigh
    g0, l1, l2 = gamma
    m1, m2 = 2 * w * l1, 2 * w * l2
    c1, c2 = l1 / 2, l2 / 2
    J1, J2 = m1 * l1 ** 2 / 12, m2 * l2 ** 2 / 12
    d2 = l1 ** 2 + c2 ** 2 + 2 * l1 * c2 * math.cos(theta2)
    M = np.array([[m1 * c1 ** 2 + J1 + m2 * d2 + J2, m2 * (c2 ** 2 + l1 * c2 * math.cos(theta2)) + J2],
                  [0.0, m2 * c2 ** 2 + J2]])
    M[1, 0] = M[0, 1]
    K = np.diag([w / (6 * (g0 + l1 / 2)), w / (6 * (l1 / 2 + l2))])
    return eigh(K, M, eigvals_only=True)


def case_poses_2r(row: Row, thetas):
    """2R against the closed form at, and beyond, the n theta = pi/2 limit."""
    beam = uniform_panel()
    gamma = [0.3, 0.3, 0.4]
    worst = 0.0
    for th in thetas:
        lam = prbdm_lam(row, beam, gamma, [th])
        row.check(f"finite, sorted, positive at theta = {th:.4g}", None, ok=is_sane(lam))
        worst = max(worst, rel_err(lam[0], _closed_form_2r(0.18, gamma, th)))
    row.check("2R vs hand-written closed form", worst, 1e-12, key=True)


def case_poses_4r(row: Row, totals):
    """4R at n theta = pi/2 and beyond: M stays SPD (its J_j term is SPD at every pose), theta_1
    turns the chain rigidly, -theta mirrors it; the command warns beyond the paper's range."""
    beam = tapered_panel()
    n = 4
    for tot in totals:
        th = tot / n
        lam = prbdm_lam(row, beam, GAMMA4, [th])
        row.check(f"finite, sorted, positive at n theta = {tot:.4g}", None, ok=is_sane(lam))
        P = np.full((1, n), th)
        Q = P.copy()
        Q[0, 0] += 0.7
        rot = prbdm_lam(Row(), beam, GAMMA4, Q, grad=False)
        mir = prbdm_lam(Row(), beam, GAMMA4, -P, grad=False)
        row.check(f"theta_1 rigid rotation, mirror (n theta = {tot:.4g})",
                  max(rel_err(rot, lam), rel_err(mir, lam)), 1e-12, key=tot == totals[-1])
    from ..parsing import parse_poses
    _, warn_lim = parse_poses(f"{math.pi / 8:.15f}", n)
    _, warn_out = parse_poses("0.5", n)
    row.check("prbdm eval: silent at the limit, warns beyond (n theta > pi/2)", None,
              ok=not warn_lim and any("pi/2" in w for w in warn_out))


def _degenerate_2r():
    """A uniform 2R model and pose where A = K^-1/2 M K^-1/2 is a multiple of the identity (the
    two eigenvalues coincide): solve A_12 = 0 and A_11 = A_22 for (theta_2, gamma_1)."""
    torch = torch1()
    from scipy.optimize import fsolve

    from prbdm import model
    bt = model.BeamTensors.from_beams(uniform_panel(0.2, 0.02))

    def F(p):
        gamma = torch.tensor([0.2, p[1], 0.8 - p[1]], dtype=torch.float64)
        links = model.links_from_gamma(bt, gamma)
        d = model.base_stiffness(bt, links).rsqrt()
        a = (d[:, None] * model.mass_matrix(links, torch.tensor([0.3, p[0]],
                                                               dtype=torch.float64))
             * d[None, :]).numpy()
        return [a[0, 1] / a[0, 0], (a[0, 0] - a[1, 1]) / a[0, 0]]

    theta2, g1 = fsolve(F, [2.5, 0.36], xtol=1e-13)
    return bt, float(theta2), float(g1)


def case_degenerate(row: Row, offset: float):
    """Nearly equal eigenvalues: eigenvalue-only gradients (eigvalsh) carry no 1/(mu_i - mu_j)
    factor, so they stay finite and match finite differences whatever the gap."""
    torch = torch1()
    from prbdm import model
    bt, theta2, g1 = _degenerate_2r()
    P = torch.tensor([[0.3, theta2 + offset]], dtype=torch.float64)
    x = torch.tensor([0.2, g1], dtype=torch.float64, requires_grad=True)
    w = bt.w.clone().requires_grad_(True)

    def lam_of(x, w):
        b = model.BeamTensors(bt.x, w, bt.length, bt.thickness, bt.E, bt.rho)
        return model.eigenvalues_unit_k(b, torch.cat([x, 1 - x.sum(-1, keepdim=True)]), P)[0]

    lam = lam_of(x, w)
    gap = float((lam[1] - lam[0]).detach() / lam[0].detach())
    beam = uniform_panel(0.2, 0.02)
    prbdm_lam(row, beam, [0.2, g1, 0.8 - g1], P.numpy(), grad=False)
    row.check("eigenvalues finite, sorted, positive", None, ok=is_sane(lam.detach().numpy()))
    grads = [torch.autograd.grad(lam[i], (x, w), retain_graph=True) for i in range(2)]
    ok = all(bool(torch.isfinite(g).all()) for gs in grads for g in gs)
    row.grads(ok)
    row.check("d lam_1, d lam_2 / d(gamma, widths) finite", None, ok=ok)
    # the pair's sum is smooth through the crossing; each eigenvalue is smooth while gap > 0
    v = torch.tensor([0.3, -0.7], dtype=torch.float64)
    h = 1e-7
    with torch.no_grad():
        fd = (lam_of(x + h * v, w) - lam_of(x - h * v, w)) / (2 * h)
    ad_sum = float((grads[0][0] + grads[1][0]) @ v)
    row.check("d(lam_1 + lam_2): autograd vs central diff.", abs(ad_sum - float(fd.sum()))
              / abs(ad_sum), 1e-6, key=True)
    if gap > 1e-4:
        ad0 = float(grads[0][0] @ v)
        row.check("d lam_1: autograd vs central diff.", abs(ad0 - float(fd[0])) / abs(ad0), 1e-5)
    row.note = f"relative gap (lam_2 - lam_1)/lam_1 = {gap:.2e}"


def case_float32(row: Row, n: int, beams: int):
    """float32 against float64 on random beams and layouts: a symmetric eigensolver's error is
    ~eps ||A|| = eps mu_max, so the relative error of lam_i = 1/mu_i is ~eps lam_i / lam_1:
    mode 1 is good to a few eps32 whatever n, the highest mode loses cond(A) = lam_n/lam_1.
    The model warns (:class:`prbdm.model.PrecisionWarning`) when 4 eps32 cond > PRECISION_RTOL or a
    result is not finite and positive: every unwarned float32 result must then be within
    PRECISION_RTOL of float64 in every mode (never a silent wrong number), and the warning must
    come where the float64 conditioning says it should (2x margin either side)."""
    torch = torch1()
    from prbdm import model
    tol = model.PRECISION_RTOL
    rng = np.random.default_rng([7, n])
    worst_ratio = err1 = errn = silent = 0.0
    sane = f64_quiet = warn_ok = unwarned_sane = True
    calls = warned = 0
    for i in range(beams):
        beam = random_beam(7, i)
        g = 0.025 + (1 - 0.025 * (n + 1)) * rng.dirichlet(np.ones(n + 1))
        for poses in ("paper", "linear"):
            with warnings.catch_warnings(record=True) as w64:
                warnings.simplefilter("always", model.PrecisionWarning)
                l64 = prbdm_lam(row, beam, g, poses)
            with warnings.catch_warnings(record=True) as w32:
                warnings.simplefilter("always", model.PrecisionWarning)
                l32 = prbdm_lam(Row(), beam, g, poses, dtype=torch.float32)
            f64_quiet &= not any(issubclass(w.category, model.PrecisionWarning) for w in w64)
            ws = [str(w.message) for w in w32 if issubclass(w.category, model.PrecisionWarning)]
            hit = bool(ws) and "float32" in ws[0] and "float64" in ws[0]
            calls, warned = calls + 1, warned + hit
            ok32 = is_sane(l32)
            sane &= ok32
            err = np.abs(l32 / l64 - 1)
            est = model.PRECISION_FACTOR * EPS32 * float((l64[..., -1] / l64[..., 0]).max())
            if est > 2 * tol:
                warn_ok &= hit
            elif est < tol / 2:
                warn_ok &= not hit
            if not hit:
                unwarned_sane &= ok32
                silent = max(silent, float(np.nan_to_num(err, nan=np.inf).max()))
            ratio = l64 / l64[..., :1]
            if ok32:
                worst_ratio = max(worst_ratio, float((err / (EPS32 * ratio)).max()))
            err1, errn = max(err1, float(err[..., 0].max())), max(errn, float(err[..., -1].max()))
    row.extra.update(f32_err1=err1, f32_errn=errn, f32_ratio=worst_ratio, f32_sane=sane,
                     f32_condA=row.cond["A"], f32_warned=warned, f32_calls=calls)
    row.check("float64: no PrecisionWarning", None, ok=f64_quiet)
    row.check(f"PrecisionWarning iff {model.PRECISION_FACTOR:g} eps32 cond > {tol:g} (2x margin), "
              "naming float32/float64",
              None, ok=warn_ok)
    row.check("unwarned float32: finite, sorted, positive", None, ok=unwarned_sane)
    row.check(f"unwarned float32: worst rel. error of any mode (never silent beyond {tol:g})",
              silent, tol)
    row.check("float32 mode-1 rel. error", err1, 1e-5, key=True)
    row.check("float32 error / (eps32 lam_i/lam_1), all modes (finite results)", worst_ratio, 50.0)
    row.note = (f"float32 rel. error: mode 1 {err1:.1e}, mode n {errn:.1e}; PrecisionWarning on "
                f"{warned} of {calls} solves" +
                ("" if sane else "; highest eigenvalues NOT all finite, sorted and positive "
                 "(warned)"))


def _start_loss(beam: Beam, omega_truth, gamma) -> float:
    """The fit's loss [%] at ``gamma`` with its least-squares SCFs (paper poses, r = n modes)."""
    torch = torch1()
    from prbdm import model
    bt = model.BeamTensors.from_beams(beam)
    g = torch.tensor(np.asarray(gamma, dtype=np.float64))
    n = len(gamma) - 1
    mu = model.eigenvalues_unit_k(bt, g, model.paper_poses(n)) * bt.lambda0
    lam = torch.as_tensor(np.asarray(omega_truth[:n], dtype=np.float64)) ** 2
    k = (mu * lam).sum(-1) / (mu * mu).sum(-1)
    return float(model.loss_percent(k[:, None] * mu, lam))


def case_fit_bounds(row: Row, corners):
    """Fits started on the gamma bounds (a corner of the bounded simplex: every link but one at
    0.025) must leave the bound and converge to a finite, feasible *local* optimum. A single start
    is a local method: its loss against the default multistart fit's is reported, not bounded
    (1.0 to 3.7 times on this beam; the multistart fit is what finds the global one)."""
    from prbdm.fit import fit_prbdm
    from prbdm.model import GAMMA_MAX, GAMMA_MIN
    from prbdm.truth.analytic import beam_omega_scale
    beam = random_beam(0, 3)
    n = 4
    truth = beam_truth(row, beam) * beam_omega_scale(beam)
    multi = fit_prbdm(beam, truth, n)
    best = multi.loss_percent
    ratios = []
    for j in corners:
        g0 = np.full(n + 1, GAMMA_MIN)
        g0[j] = 1 - n * GAMMA_MIN
        start = _start_loss(beam, truth, g0)
        f = fit_prbdm(beam, truth, n, init_gamma=[g0])
        again = fit_prbdm(beam, truth, n, init_gamma=[f.gamma])
        g = f.gamma
        row.check(f"corner {j}: finite, sum 1, within bounds", float(abs(g.sum() - 1)), 1e-12,
                  ok=bool(np.all(np.isfinite(g)) and np.all(np.isfinite(f.k)) and np.all(f.k > 0)
                          and abs(g.sum() - 1) < 1e-12 and g.min() >= GAMMA_MIN - 1e-12
                          and g.max() <= GAMMA_MAX + 1e-12 and math.isfinite(f.loss_percent)))
        row.check(f"corner {j}: left the start (-max change of gamma)", -float(np.abs(g - g0).max()),
                  -1e-3)
        row.check(f"corner {j}: loss / loss at the start (best k)", f.loss_percent / start, 0.999)
        row.check(f"corner {j}: converged (re-fit gains < 2 %)",
                  1 - again.loss_percent / f.loss_percent, 0.02)
        ratios.append(f.loss_percent / best)
        row.check(f"corner {j}: loss / {multi.n_starts}-start loss (local optimum, reported)",
                  ratios[-1], None, ok=math.isfinite(ratios[-1]))
        row.grads(True)
    row.check(f"worst loss / {multi.n_starts}-start loss (local optimum from the bound, reported)",
              max(ratios), None, ok=True, key=True)
    row.note = (f"local optima from the bounds, reported: loss {multi.n_starts}-start "
                f"{best:.3g} %, from corner(s) " + ", ".join(
                    f"{j}: {r * best:.3g} % ({r:.2f}x)" for j, r in zip(corners, ratios)))


def case_network(row: Row, beam: Beam, expect_ood: bool):
    """The network on a shape: an OutOfDistributionWarning naming the feature when a feature lies
    outside the training range (``expect_ood`` True), saying that no training panel is like it
    (``"unlike"``: every feature in range, the combination not); otherwise none. Where every
    feature is in range its truth-frequency prediction must be close."""
    from prbdm import surrogate
    from prbdm.surrogate.features import FeatureSpec, feature_names
    from prbdm.truth import bending_frequencies
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pred = surrogate.predict([beam], joints=4)
    ood = [str(w.message) for w in caught
           if issubclass(w.category, surrogate.OutOfDistributionWarning)]
    names = feature_names(FeatureSpec())
    named = bool(ood) and any(nm in ood[0] for nm in names)
    g = pred.gamma[0]
    row.check("gamma on the bounded simplex, k > 0, omega finite", None,
              ok=bool(abs(g.sum() - 1) < 1e-12 and g.min() >= 0.025 - 1e-12
                      and np.all(pred.k > 0) and is_sane(pred.omega[0])
                      and np.all(np.isfinite(pred.omega_truth))))
    truth = bending_frequencies(beam, "beam", 5).omega
    err = rel_err(pred.omega_truth[0][:4], truth[:4])
    if expect_ood == "unlike":
        row.check("OutOfDistributionWarning: unlike every training panel", None,
                  ok=bool(ood) and "no training panel" in ood[0])
        row.check("truth-frequency error, modes 1-4 (features in range)", err, 0.02, key=True)
    elif expect_ood:
        row.check("OutOfDistributionWarning naming the feature", None, ok=named)
        row.check("truth-frequency error (extrapolation, reported)", err, None, ok=True,
                  key=True)
        row.extra["network_error"] = err
    else:
        row.check("no OutOfDistributionWarning", None, ok=not ood)
        row.check("truth-frequency error, modes 1-4 (in range)", err, 0.02, key=True)
    row.grads(True)
    row.note = (ood[0][:110] + "...") if ood else "no warning"


def case_refusals(row: Row):
    """Bad input is a BadInput naming the field, never a number."""
    from prbdm import model
    from prbdm.fit import fit_prbdm
    from prbdm.truth import bending_frequencies
    torch = torch1()
    beam = uniform_panel()
    g4 = torch.tensor(GAMMA4, dtype=torch.float64)
    tries = [
        ("truth: width ratio 1e7", "half_width", lambda: bending_frequencies(
            Beam(x=[0, 1], half_width=[0.1, 1e-8], thickness=0.02), "beam")),
        ("PRBDM: width ratio 1e13", "half_width", lambda: model.eigenvalues(
            Beam(x=[0, 1], half_width=[0.1, 1e-14], thickness=0.02), g4)),
        ("fit: joints = 40 (bounds infeasible)", "joints",
         lambda: fit_prbdm(beam, [1.0, 2.0], 40)),
        ("PRBDM: NaN pose", "poses", lambda: model.eigenvalues(beam, g4, poses=[float("nan")])),
        ("PRBDM: one link", "gamma", lambda: model.eigenvalues(beam, torch.tensor([1.0]))),
        ("beam: zero width", "half_width", lambda: Beam(x=[0, 1], half_width=[0.1, 0.0],
                                                        thickness=0.02)),
        ("beam: thickness 0", "thickness", lambda: uniform_panel(thickness=0.0)),
        ("material: E = 0", "material.E", lambda: Material(E=0.0)),
        ("fit: truth not ascending", "omega_truth",
         lambda: fit_prbdm(beam, [3.0, 2.0, 1.0, 4.0], 3)),
    ]
    for name, fld, fn in tries:
        ok, msg = refused(fn, fld)
        row.check(f"{name} -> BadInput naming {fld}", None, ok=ok)
    row.conds()


# ============================================================================ the suite
def _cases() -> list[Case]:
    c = []
    ref_u = uniform_panel()
    for t in (0.001, 0.05):
        c.append(Case(f"thickness {t * 1e3:g} mm", "t (uniform steel panel, L = 1 m, w = 0.18 m)",
                      case_scaling, dict(beam=uniform_panel(thickness=t), ref=ref_u,
                                         analytic=True)))
    for w in (0.002, 0.5):
        c.append(Case(f"half-width {w * 1e3:g} mm", "w (uniform steel panel, t = 20 mm)",
                      case_scaling, dict(beam=uniform_panel(half_width=w), ref=ref_u,
                                         analytic=True)))
    c.append(Case("combined: 2 mm wide, 1 mm thick elastomer, L = 3 m", "everything at once",
                  case_scaling, dict(beam=uniform_panel(0.002, 0.001, ELASTOMER, 3.0), ref=ref_u,
                                     analytic=True), quick=False))
    ref_t = tapered_panel()
    for name, mat in (("steel", STEEL), ("aluminium", ALUMINIUM), ("titanium", TITANIUM),
                      ("elastomer 5 MPa", ELASTOMER)):
        c.append(Case(f"material: {name}", f"E = {mat.E:.3g} Pa, rho = {mat.rho:g} (tapered panel)",
                      case_scaling, dict(beam=tapered_panel(mat), ref=ref_t, analytic=False)))
    c.append(Case("width 100:1 linear taper", "w 0.5 m -> 5 mm", case_width,
                  dict(beam=Beam(x=[0, 1], half_width=[0.5, 0.005], thickness=0.02),
                       order=True, shoot_modes=2)))
    c.append(Case("width 100:1 step over 1 % of span", "w 0.2 m -> 2 mm at x = 0.5-0.51 L",
                  case_width, dict(beam=Beam(x=[0, 0.5, 0.51, 1], half_width=[0.2, 0.2, 2e-3, 2e-3],
                                             thickness=0.02),
                                   order=False, shoot_modes=2)))
    c.append(Case("needle tip (1e5:1)", "w 0.1 m -> 1 um at the tip (plate: refused)",
                  case_width, dict(beam=Beam(x=[0, 1], half_width=[0.1, 1e-6], thickness=0.02),
                                   order=True, shoot_modes=2, plate="refused")))
    c.append(Case("width 100:1 taper, plate truth", "w 0.5 m -> 5 mm; plate FEM too",
                  case_width, dict(beam=Beam(x=[0, 1], half_width=[0.5, 0.005], thickness=0.02),
                                   order=True, shoot_modes=3, plate="finite"), quick=False))
    c.append(Case("needle tip (1e4:1), plate truth", "w 0.1 m -> 10 um; plate FEM too",
                  case_width, dict(beam=Beam(x=[0, 1], half_width=[0.1, 1e-5], thickness=0.02),
                                   order=True, shoot_modes=3, plate="slender"), quick=False))
    c.append(Case("needle tip 1e11:1", "beyond the truth's 1e6", case_needle_beyond,
                  dict(tip=1e-12)))
    c.append(Case("needle tip 1e15:1", "beyond the PRBDM's 1e12", case_needle_beyond,
                  dict(tip=1e-16)))
    for n in (1, 2, 3, 4, 5, 8, 10, 15, 20, 30, 39):
        c.append(Case(f"n = {n}", "joints (uniform panel; random gamma, paper poses)",
                      case_joints, dict(n=n), quick=n in (1, 4, 20)))
    c.append(Case("poses 2R: 0, pi/4 (limit), 1, 3 rad", "theta_2 (theta_1 = theta_2)",
                  case_poses_2r, dict(thetas=[0.0, math.pi / 4, 1.0, 3.0])))
    c.append(Case("poses 4R: n theta = pi/2 (limit), pi, 2 pi", "pose (tapered panel)",
                  case_poses_4r, dict(totals=[math.pi / 2, math.pi, 2 * math.pi])))
    for off in (1e-2, 1e-5, 1e-8, 0.0):
        c.append(Case(f"near-equal eigenvalues, offset {off:g}",
                      "2R pose offset from an exact crossing", case_degenerate,
                      dict(offset=off)))
    for n in (1, 2, 4, 8, 12, 20, 39):
        c.append(Case(f"float32, n = {n}", "dtype (8 random beams, paper + linear poses)",
                      case_float32, dict(n=n, beams=8),
                      quick=n in (2, 4, 20, 39)))
    varied = "init_gamma on the bounds (4R, random beam); vs the multistart fit"
    c.append(Case("fit from gamma corners 0, 4", varied, case_fit_bounds, dict(corners=[0, 4])))
    c.append(Case("fit from all gamma corners", varied, case_fit_bounds,
                  dict(corners=[0, 1, 2, 3, 4]), quick=False,
                  known_failure="corner 2: a re-fit from its own result still gains 14 % (check: "
                  "< 2 %); init_gamma lifts links off the bounds, so the re-fit is a new start, "
                  "not a continuation (docs/stability.md, Limitations)"))
    c.append(Case("network: in-range beam", "random_beam(0, 100000), unseen", case_network,
                  dict(beam=random_beam(0, 100000), expect_ood=False)))
    c.append(Case("network: needle tip 1e5:1", "shape", case_network,
                  dict(beam=Beam(x=[0, 1], half_width=[0.1, 1e-6], thickness=0.02),
                       expect_ood=False), quick=False))
    # inside the per-feature training range of the 80,000-beam checkpoint, but unlike every
    # training panel (nearest 13.6 against a held-out p99.9 of 8.6): the warning that says so,
    # and the in-range accuracy is still required
    c.append(Case("network: 100:1 step", "shape at the edge of training", case_network,
                  dict(beam=Beam(x=[0, 0.5, 0.51, 1], half_width=[0.2, 0.2, 2e-3, 2e-3],
                                 thickness=0.02), expect_ood="unlike")))
    c.append(Case("network: 1e4:1 step", "shape outside training", case_network,
                  dict(beam=Beam(x=[0, 0.5, 0.51, 1], half_width=[0.2, 0.2, 2e-5, 2e-5],
                                 thickness=0.02), expect_ood=True), quick=False))
    c.append(Case("bad input", "9 invalid inputs", case_refusals, {}))
    return c


CASES = _cases()


def run_suite(quick: bool = False) -> list[dict]:
    """Run every case (``quick``: the subset the tests run, about a minute on 2 busy cores) and
    return one dict per case: name, varied, passed, n_checks, failed (names), checks (each
    check's value, tolerance, verdict), accuracy / tolerance / accuracy_check (the check nearest
    its tolerance), cond_M, cond_K, cond_A, cond_fem_raw, cond_fem (None where not computed),
    grad_finite, time_s, note."""
    return [run_case(c) for c in CASES if c.quick or not quick]
