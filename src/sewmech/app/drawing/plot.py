"""Plots of kinematics results. Every function takes ``ax=None`` and returns the axes.

matplotlib is imported lazily; the CLI selects the non-interactive Agg backend.
"""

from __future__ import annotations

import numpy as np

from ...engine.results import KinematicsResult


def _axes(ax, nrows=1):
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt  # lazy: importing sewmech never pulls in pyplot

    fig, axs = plt.subplots(nrows, 1, figsize=(8, 2.6 * nrows), sharex=True,
                            constrained_layout=True)
    return axs


def plot_motion(result: KinematicsResult, channel_base: str, *, ax=None, label: str | None = None):
    """Motion diagram: position, velocity and acceleration of one point coordinate, one link
    angle or one joint variable against the shaft angle in degrees.

    Parameters
    ----------
    channel_base : str
        ``"B_y"`` (point B, y coordinate), ``"link:rocker"`` or ``"var:needle_bar"``.
    ax : sequence of 3 Axes, optional
    """
    if result.batch_shape:
        raise ValueError("plot_motion draws one design; index the batch first")
    if channel_base.startswith("link:"):
        n = channel_base[5:]
        names = [f"theta_{n}", f"omega_{n}", f"epsilon_{n}"]
    elif channel_base.startswith("var:"):
        n = channel_base[4:]
        names = [f"q_{n}", f"qd_{n}", f"qdd_{n}"]
    else:
        names = [f"p_{channel_base}", f"v_{channel_base}", f"a_{channel_base}"]
    axs = _axes(ax, 3)
    x = result.phi_deg
    for a, name in zip(axs, names):
        values, unit = result.channel(name)
        if name.startswith("theta_") or (name.startswith("q_") and unit == "rad"):
            values = np.degrees(np.unwrap(values))
            unit = "deg"
        a.plot(x, values, label=label or name)
        a.set_ylabel(f"{name}\n[{unit}]")
        a.grid(True, alpha=0.3)
    axs[-1].set_xlabel("shaft angle phi [deg]")
    return axs


def plot_path(result: KinematicsResult, point: str, *, ax=None, **kw):
    """Path of a point in the mechanism plane (mm), equal axes."""
    ax = _axes(ax, 1)
    p = result.point(point).p
    ax.plot(p[..., 0].T if p.ndim > 2 else p[:, 0], p[..., 1].T if p.ndim > 2 else p[:, 1], **kw)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(True, alpha=0.3)
    return ax
