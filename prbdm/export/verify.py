"""An exported MJCF checked in MuJoCo: its small-vibration frequencies from MuJoCo's own mass
matrix (:func:`mujoco_linear_frequencies`) and a free vibration integrated by MuJoCo
(:func:`mujoco_free_vibration`). Needs the ``sim`` extra (mujoco)."""
from __future__ import annotations

import math

import numpy as np

from ..signals import zero_crossing_period


def mujoco_linear_frequencies(xml: str, qpos=None):
    """Small-vibration frequencies [rad/s] of an MJCF chain of spring hinges about ``qpos``
    (default: the ``rest`` keyframe, i.e. the spring reference): mass matrix from
    ``mujoco.mj_fullM`` at that pose, stiffness from ``model.jnt_stiffness``. Needs mujoco."""
    import mujoco
    from scipy.linalg import eigh

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos_spring if qpos is None else qpos
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    if hasattr(data, "qM"):                 # MuJoCo 3: mj_fullM(m, dst, qM)
        mujoco.mj_fullM(model, M, data.qM)
    else:                                   # MuJoCo 4: mj_fullM(m, d, dst)
        mujoco.mj_fullM(model, data, M)
    K = np.diag(model.jnt_stiffness.copy())
    lam, vec = eigh(K, M)
    return np.sqrt(lam), vec


def mujoco_free_vibration(xml: str, amplitude: float = 1e-4, periods: float = 10.0,
                          steps_per_period: int = 200, mode: int = 0):
    """Free vibration in MuJoCo: gravity off, no damping, released from the spring reference
    plus ``amplitude`` (rad, largest joint) times linear mode ``mode``; RK4 with
    ``steps_per_period`` steps per period of the highest mode. Returns (t, q_tip_angle_sum,
    measured omega of the tracked mode by zero crossings, predicted omega)."""
    import mujoco

    omega, vec = mujoco_linear_frequencies(xml)
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.gravity[:] = 0.0
    model.dof_damping[:] = 0.0
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = 2 * math.pi / omega.max() / steps_per_period
    data = mujoco.MjData(model)
    v = vec[:, mode] / np.abs(vec[:, mode]).max()
    data.qpos[:] = model.qpos_spring + amplitude * v
    steps = int(math.ceil(periods * 2 * math.pi / omega[mode] / model.opt.timestep))
    y = np.empty(steps + 1)
    w = v / (v @ v)                         # the mode's coordinate of the joint deflection
    y[0] = (data.qpos - model.qpos_spring) @ w
    for s in range(steps):
        mujoco.mj_step(model, data)
        y[s + 1] = (data.qpos - model.qpos_spring) @ w
    t = np.arange(steps + 1) * model.opt.timestep
    return t, y, 2 * math.pi / zero_crossing_period(t, y), float(omega[mode])
