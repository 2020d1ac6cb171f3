"""The held-out test a checkpoint records (metadata ``test``): one home for the training script,
which measures it on its test split, and ``retest.py``, which measures it again for a saved
checkpoint (e.g. to add the per-width bands to one trained before they existed).

The measures: the PRBDM loss of the network's (gamma, k) against the truth (%, the paper's loss,
docs/conventions.md §3), the frequency objective (worst mode over the poses, %), the optimised
fits' loss where the set holds fits, the error of each predicted truth frequency, and all of them
again per full-width band (``by_width``), which an answer for a panel of that width quotes.
"""
from __future__ import annotations

import time

import numpy as np


def test_metrics(sur, batch, omega_truth, r: int, loss_fit) -> dict:
    """The test record of the network ``sur`` (a :class:`prbdm.surrogate.Surrogate`) on the beams
    of ``batch`` (a BeamBatch), whose truth angular frequencies [rad/s] are ``omega_truth``
    (B, R); ``r`` modes enter the loss; ``loss_fit`` (B,) the optimised fits' loss [%], NaN in a
    truth-only set."""
    import torch

    from prbdm import objectives
    from prbdm.chain import loss_percent_np
    from prbdm.surrogate.checkpoint import accuracy_by_width

    omega_truth = np.asarray(omega_truth, dtype=np.float64)
    t0 = time.perf_counter()
    pred = sur.predict(batch, frequencies=True, warn=False)
    pred_time = time.perf_counter() - t0
    lam_net = (pred.omega / np.sqrt(batch.lambda0)[:, None, None]) ** 2
    lam_hat = omega_truth[:, :r] ** 2 / batch.lambda0[:, None]
    loss_net = loss_percent_np(lam_net, lam_hat, r)
    freq_net = objectives.frequency_measure(torch.as_tensor(lam_net), torch.as_tensor(lam_hat),
                                            r).numpy()
    ferr = np.abs(pred.omega_truth / omega_truth - 1)
    loss_fit = np.asarray(loss_fit, dtype=np.float64)
    has_fit = bool(np.isfinite(loss_fit).all())
    beams = len(loss_net)
    return {"beams": int(beams),
            "loss_median": float(np.median(loss_net)),
            "loss_p95": float(np.percentile(loss_net, 95)),
            "loss_mean": float(loss_net.mean()), "loss_max": float(loss_net.max()),
            "frequency_median": float(np.median(freq_net)),
            "frequency_p95": float(np.percentile(freq_net, 95)),
            "fit_loss_median": float(np.median(loss_fit)) if has_fit else None,
            "fit_loss_p95": float(np.percentile(loss_fit, 95)) if has_fit else None,
            "freq_err_median": np.median(ferr, 0).tolist(),
            "freq_err_p95": np.percentile(ferr, 95, 0).tolist(),
            "out_of_range_beams": int(pred.ood.any(1).sum()),
            "predict_time_s_per_beam": pred_time / beams,
            "evaluated_with": "prbdm.surrogate.load_checkpoint + predict (NumPy path)",
            "by_width": accuracy_by_width(2 * batch.w.max(1), loss_net, ferr)}


def describe(test: dict) -> list[str]:
    """The test record as log lines: the whole test, then one line per width band."""
    fits = (f"optimised fits: median {test['fit_loss_median']:.4f} % p95 "
            f"{test['fit_loss_p95']:.4f} %" if test["fit_loss_median"] is not None
            else "no fits in a truth-only set")
    lines = [f"test ({test['beams']} beams): PRBDM loss median {test['loss_median']:.4f} % p95 "
             f"{test['loss_p95']:.4f} % ({fits}); frequency objective median "
             f"{test['frequency_median']:.4f} % p95 {test['frequency_p95']:.4f} %; "
             f"freq-prediction error median per mode "
             f"{[round(e * 100, 3) for e in test['freq_err_median']]} %"]
    for b in test.get("by_width", []):
        lines.append(f"  full width {b['full_width'][0]:g}-{b['full_width'][1] or 'inf'} L "
                     f"({b['beams']} beams): loss median {b['loss_median']:.4f} % p95 "
                     f"{b['loss_p95']:.4f} %; freq error median per mode "
                     f"{[round(e * 100, 3) for e in b['freq_err_median']]} %")
    return lines
