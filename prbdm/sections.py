"""Exact integrals of a piecewise-linear planform over spans [a, b], in torch.

For a span of the beam these give the link mass, centre of mass and rotary inertia (docs/conventions.md §3), and
the compliance integral of the ``beam`` stiffness law. They are exact for a piecewise-linear
half-width, batched over leading dimensions and differentiable with respect to the cut positions.

How: each planform segment [x_k, x_k+1] is clipped to the span; on the clipped piece the half-width
is linear, so ``s^p w(s)`` is a polynomial of degree <= 3 and Simpson's rule integrates it exactly.
Moments are taken about the span's midpoint, so a short link far from the root keeps its digits
(no ``I_root - m x_c^2`` cancellation). The compliance ``∫ ds / w`` over a linear piece is
``h / logmean(w_lo, w_hi)``, evaluated with a series where the two widths nearly agree.

All lengths here are in units of the beam length L (stations in [0, 1]).
"""
from __future__ import annotations

import torch

__all__ = ["span_integrals", "SpanIntegrals"]


class SpanIntegrals(tuple):
    """(area, first, second, compliance) of spans, each shaped like the span bounds.

    area       = ∫_a^b 2 w(s) ds                      (full-width area)
    first      = ∫_a^b 2 w(s) (s - mid) ds            (mid = (a + b) / 2)
    second     = ∫_a^b 2 w(s) (s - mid)^2 ds
    compliance = ∫_a^b ds / w(s)
    """

    __slots__ = ()

    def __new__(cls, area, first, second, compliance):
        return super().__new__(cls, (area, first, second, compliance))

    area = property(lambda self: self[0])
    first = property(lambda self: self[1])
    second = property(lambda self: self[2])
    compliance = property(lambda self: self[3])

    @property
    def centroid(self):
        """Centre of area, measured from the span midpoint."""
        return self.first / self.area

    @property
    def central_second(self):
        """Second moment of area about the centroid along x: ∫ 2 w (s - s_c)^2 ds."""
        return self.second - self.first ** 2 / self.area


def _inv_logmean(lo, hi):
    """1 / logmean(lo, hi) = log(hi / lo) / (hi - lo), stable (and with finite gradients) when
    hi ≈ lo."""
    u = (hi - lo) / lo
    small = u.abs() < 1e-3
    u_safe = torch.where(small, torch.ones_like(u), u)
    exact = torch.log1p(u_safe) / u_safe
    series = 1 - u / 2 + u * u / 3 - u * u * u / 4
    return torch.where(small, series, exact) / lo


#: a planform with more stations than this is integrated by prefix sums over its segments,
#: O(S + C log S), instead of clipping every segment to every span, O(C S): a fit of a planform
#: of 100,000 stations (``--all-stations``) went from about 300 s to seconds. Below it the
#: clipping is kept: exact to the last digit for short links far from the root, where the prefix
#: sums' moments about the origin lose about h^2/12 of their digits (1e-12 relative at h = 0.025)
CUMULATIVE_ABOVE = 256


def span_integrals(x, w, a, b, *, compliance: bool = True) -> SpanIntegrals:
    """Integrals of the planform over spans ``[a, b]``.

    x, w: (..., S) stations and half-widths (strictly increasing stations, except that repeated
    trailing stations, used to pad beams to a common S, are allowed). a, b: (..., C) span bounds
    with a <= b, inside [x_0, x_last]. Leading dimensions broadcast. Returns :class:`SpanIntegrals`
    of shape (..., C).
    """
    if x.shape[-1] > CUMULATIVE_ABOVE:
        return _span_integrals_by_prefix_sums(x, w, a, b, compliance)
    xk, xk1 = x[..., None, :-1], x[..., None, 1:]
    wk, wk1 = w[..., None, :-1], w[..., None, 1:]
    a_, b_ = a[..., :, None], b[..., :, None]
    # the span clipped to the segment: both ends stay inside [x_k, x_k+1], so the half-width
    # below is interpolated, never extrapolated (a segment outside the span has h = 0 and
    # widths of its own, positive, wherever the stations fall relative to the cuts)
    lo = torch.minimum(torch.maximum(a_, xk), xk1)
    hi = torch.maximum(torch.minimum(b_, xk1), lo)
    dx = xk1 - xk
    has_length = dx > 0
    slope = torch.where(has_length, (wk1 - wk) / torch.where(has_length, dx, torch.ones_like(dx)),
                        torch.zeros_like(dx))
    w_lo = wk + slope * (lo - xk)
    w_hi = wk + slope * (hi - xk)
    h = hi - lo
    mid = (a_ + b_) / 2
    p, q = lo - mid, hi - mid
    m, w_m = (p + q) / 2, (w_lo + w_hi) / 2
    # Simpson's rule, exact for the cubic s^2 w(s); factor 2 for the full width
    area = (h * (w_lo + w_hi)).sum(-1)
    first = (h / 3 * (p * w_lo + 4 * m * w_m + q * w_hi)).sum(-1)
    second = (h / 3 * (p * p * w_lo + 4 * m * m * w_m + q * q * w_hi)).sum(-1)
    if compliance:
        comp = (h * _inv_logmean(w_lo, w_hi)).sum(-1)
    else:
        comp = torch.zeros_like(area)
    return SpanIntegrals(area, first, second, comp)


def _pieces(h, xa, wa, wb, compliance: bool):
    """Integrals over [xa, xa + h] of 2 w, 2 s w, 2 s^2 w (Simpson, exact for these cubics) and
    of 1 / w, for w linear from wa to wb."""
    xb = xa + h
    xm, wm = xa + h / 2, (wa + wb) / 2
    out = [h * (wa + wb), h / 3 * (xa * wa + 4 * xm * wm + xb * wb),
           h / 3 * (xa * xa * wa + 4 * xm * xm * wm + xb * xb * wb)]
    out.append(h * _inv_logmean(wa, wb) if compliance else torch.zeros_like(h))
    return out


def _span_integrals_by_prefix_sums(x, w, a, b, compliance: bool) -> SpanIntegrals:
    """:func:`span_integrals` for many stations: the integrals from 0 to each bound are the
    prefix sums of the whole segments before it plus the part of its own segment, and a span's
    are their differences; moments about the span's midpoint from those about the origin."""
    lead = torch.broadcast_shapes(x.shape[:-1], a.shape[:-1], b.shape[:-1])
    S, C = x.shape[-1], a.shape[-1]
    x = x.expand(*lead, S).contiguous()
    w = w.expand(*lead, S)
    q = torch.cat([a.expand(*lead, C), b.expand(*lead, C)], -1).contiguous()
    xk, wk, h = x[..., :-1], w[..., :-1], x[..., 1:] - x[..., :-1]
    full = _pieces(h, xk, wk, w[..., 1:], compliance)
    prefix = [torch.nn.functional.pad(torch.cumsum(f, -1), (1, 0)) for f in full]
    k = (torch.searchsorted(xk.contiguous(), q, right=True) - 1).clamp(0, S - 2)
    xq, wq, hq = (torch.gather(v, -1, k) for v in (xk, wk, h))
    has_length = hq > 0
    slope = torch.where(has_length,
                        (torch.gather(w[..., 1:], -1, k) - wq)
                        / torch.where(has_length, hq, torch.ones_like(hq)), torch.zeros_like(hq))
    dq = torch.minimum((q - xq).clamp_min(0.0), hq)
    part = _pieces(dq, xq, wq, wq + slope * dq, compliance)
    F = [torch.gather(c, -1, k) + p for c, p in zip(prefix, part)]
    m0, m1, m2, mc = (f[..., C:] - f[..., :C] for f in F)
    mid = (a + b) / 2
    first = m1 - mid * m0
    second = m2 - 2 * mid * m1 + mid * mid * m0
    return SpanIntegrals(m0, first, second, mc)
