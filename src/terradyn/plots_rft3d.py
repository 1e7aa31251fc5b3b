"""Figures for 3D RFT: a body with its element tractions, and its force series."""
from __future__ import annotations

import numpy as np
import xarray as xr

from .plots import STYLE, _save


def body_tractions(body, frame: dict, series: xr.Dataset | None = None, path=None,
                   title: str = "", surface: float = 0.0, n_arrows: int = 40):
    """The body at one pose, each triangle coloured by the magnitude of its traction (kPa),
    arrows for the largest element forces, the free surface as a grey plane; with ``series``
    a second panel of the force components along the motion.

    ``frame``: one sample of :func:`terradyn.rft3d.element_tractions` (keys r, traction, force,
    depth, each without the step axis) plus ``vertices`` (V, 3) world positions of the mesh."""
    import matplotlib.pyplot as plt

    ncol = 2 if series is not None else 1
    with plt.rc_context(STYLE):
        fig = plt.figure(figsize=(5.5 * ncol, 4.5))
        _draw(fig, ncol, body, frame, series, title, surface, n_arrows)
    return _save(fig, path)


def _draw(fig, ncol, body, frame, series, title, surface, n_arrows):
    from matplotlib import cm, colors
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    ax = fig.add_subplot(1, ncol, 1, projection="3d")
    V = frame["vertices"] * 100  # cm
    tri = V[body.faces]
    mag = np.linalg.norm(frame["traction"], axis=-1) / 1e3  # kPa
    norm = colors.Normalize(0, max(mag.max(), 1e-9))
    cmap = cm.viridis
    fc = cmap(norm(mag))
    fc[mag == 0] = (0.85, 0.85, 0.85, 0.35)  # elements without load: faint
    ax.add_collection3d(Poly3DCollection(tri, facecolors=fc, edgecolors=(0, 0, 0, 0.08), linewidths=0.2))
    f = frame["force"]
    fm = np.linalg.norm(f, axis=-1)
    if fm.max() > 0:
        idx = np.argsort(fm)[::-1][:n_arrows]
        idx = idx[fm[idx] > 0]
        r = frame["r"][idx] * 100
        span = np.ptp(V, axis=0).max()
        d = f[idx] / fm.max() * 0.35 * span
        ax.quiver(r[:, 0], r[:, 1], r[:, 2], d[:, 0], d[:, 1], d[:, 2], color="crimson",
                  linewidth=0.8, label="element force (largest, scaled)")
    lo, hi = V.min(0), V.max(0)
    c = (lo + hi) / 2
    h = np.ptp(V, axis=0).max() / 2 * 1.1
    xx, yy = np.meshgrid([c[0] - h, c[0] + h], [c[1] - h, c[1] + h])
    ax.plot_surface(xx, yy, np.full_like(xx, surface * 100), color="0.5", alpha=0.15)
    ax.set_xlim(c[0] - h, c[0] + h)
    ax.set_ylim(c[1] - h, c[1] + h)
    ax.set_zlim(c[2] - h, c[2] + h)
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.set_zlabel("z (cm)")
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=ax, shrink=0.6, pad=0.1, label="traction magnitude (kPa)")
    if fm.max() > 0:
        ax.legend(loc="lower left", fontsize=7)
    # look at the loaded side: the force-weighted mean outward normal of the loaded elements
    nrm = frame.get("normal")
    if nrm is not None and fm.max() > 0:
        m = (fm[:, None] * nrm).sum(0)
        if np.linalg.norm(m) > 0:
            m = m / np.linalg.norm(m)
            ax.view_init(elev=float(np.clip(np.degrees(np.arcsin(m[2])), -10, 60)),
                         azim=float(np.degrees(np.arctan2(m[1], m[0]))) + 20)
    else:
        ax.view_init(elev=18, azim=-75)
    ax.set_title(title or body.name, fontsize=10)
    if series is not None:
        ax2 = fig.add_subplot(1, 2, 2)
        xname = "angle" if "angle" in series.coords else "time"
        x = series[xname].values
        for v, ls in (("Fx", "-"), ("Fy", "--"), ("Fz", "-")):
            ax2.plot(x, series[v].values, ls, label=f"{v} (N)")
        ax2.set_xlabel("rotation angle (deg)" if xname == "angle" else "time (s)")
        ax2.set_ylabel("force on the body (N)")
        ax2.axhline(0, color="k", lw=0.5)
        if "frame_x" in frame:
            ax2.axvline(frame["frame_x"], color="0.4", ls=":", lw=1, label="frame shown")
        ax2.legend(fontsize=8)
        ax2.set_title("net force", fontsize=10)
