"""Figures of a sweep."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..effects import Effects
from ..params import GearParams
from .settings import SweepSettings, sweepable

if TYPE_CHECKING:  # an annotation only: result.py imports this module to draw
    from .result import SweepResult


# -- output -----------------------------------------------------------------------------------
def _axis_label(name: str) -> str:
    unit = sweepable().get(name, "")
    return f"{name} ({unit})" if unit and unit != "1" else name


def sweep_title(name: str, s: SweepSettings) -> str:
    """Figure title: what is swept and the operating point held (speed, torque, mu, the
    changed gear data) with the effects."""
    over = dict(s.params)
    held = [f"{s.speed_rpm:g} r/min" if name != "speed_rpm" else None,
            f"{s.torque:g} N.m" if name != "torque" else None,
            f"mu {over.get('mu', GearParams().mu):g}" if name != "mu" else None]
    held += [f"{k} {v:g}" for k, v in over.items() if k not in ("mu", name)]
    eff = f"friction {s.friction}, stiffness {s.stiffness}, sliding {s.sliding}, tie {s.stick_tie}"
    if not s.separation:
        eff += ", no separation"
    shown = ("friction", "stiffness", "sliding", "stick_tie", "separation")
    fx, default = s.effects().values(), Effects().values()
    eff += "".join(f", {k} {v:g}" if isinstance(v, float) else f", {k} {v}"
                   for k, v in fx.items() if k not in shown and v != default[k])
    return (f"sweep of {name} at {', '.join(h for h in held if h)}\n{eff}; "
            f"rtol {s.rtol:g}")


def plot_sweep(result: SweepResult, path: str | Path, title: str | None = None) -> Path:
    """Ratios against the swept value (Figs. 15, 17, 18) over the Poincare section of the DTE
    (Fig. 16); failed points are red crosses on the axis, invalid ones (refused values,
    outside the model) grey ones; neither takes part in the axis scaling."""
    from matplotlib.figure import Figure

    x = np.array(result.values)
    ok = np.array([r["status"] == "ok" for r in result.records])
    fig = Figure(figsize=(7.0, 6.5), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(x[ok], result.column("stick_ratio")[ok], "o-", ms=3, label="stick ratio $r_k$")
    ax1.plot(x[ok], result.column("contact_loss_ratio")[ok], "s-", ms=3,
             label="contact-loss ratio $r_l$")
    bad = np.array([r["status"] == "failed" for r in result.records])
    inval = np.array([r["status"] == "invalid" for r in result.records])
    if bad.any():
        ax1.plot(x[bad], np.zeros(bad.sum()), "rx", ms=8, label="failed point")
    if inval.any():
        ax1.plot(x[inval], np.zeros(inval.sum()), "x", color="0.5", ms=8,
                 label="invalid (outside the model)")
    ax1.set_ylabel("ratio (Eqs. 26-27)")
    ax1.legend(loc="best", fontsize=8)
    ax1.grid(alpha=0.3)
    for r, v in zip(result.records, x, strict=True):
        if r["poincare"] and r["status"] == "ok":
            p = np.asarray(r["poincare"]) * 1e6
            ax2.plot(np.full(p.size, v), p, ",", color="k", alpha=0.6)
            ax2.plot([v], [p[0]], ".", ms=1.5, color="k")
    ax2.set_xlabel(_axis_label(result.name))
    ax2.set_ylabel("DTE, one sample per mesh period (um)")
    ax2.grid(alpha=0.3)
    s = result.settings
    fig.suptitle(title or sweep_title(result.name, s), fontsize=10)
    fig.savefig(path, dpi=120)
    return Path(path)




def _slice_label(point: dict[str, float]) -> str:
    return "_".join(f"{k}={v:g}" for k, v in point.items())


def plot_maps(store: str | Path, prefix: str | Path,
              slices: dict[str, float] | None = None) -> list[Path]:
    """Maps of the stick ratio (and of the contact-loss ratio where it is not zero
    everywhere) over the first two swept parameters of a stored grid.

    Two parameters: one figure, ``PREFIX_map.png``. More: one figure per combination of
    the other parameters' values, ``PREFIX_map_NAME=VALUE....png``; ``slices``
    (``{name: value}``, the nearest grid value) keeps only the combinations with those
    values. Points not ok (failed, invalid, not run) are left blank. A list of points is
    drawn as a scatter over its first two parameters.
    """
    import itertools

    from matplotlib.figure import Figure

    from .store import STATUS, open_dataset

    ds = open_dataset(store).load()
    grid_names = list(ds.attrs["grid"]["names"])
    ok = (ds["done"] == 1) & (ds["status"] == STATUS.index("ok"))
    prefix = Path(prefix)
    out: list[Path] = []
    x, y = grid_names[:2]
    if ds.attrs["grid"]["kind"] == "points":
        jobs = [({}, ds, f"{prefix}_map.png")]
    else:
        others = grid_names[2:]
        chosen = []
        for n in others:
            vals = ds[n].values
            if slices and n in slices:
                vals = [vals[int(np.argmin(np.abs(vals - slices[n])))]]
            chosen.append([float(v) for v in vals])
        jobs = []
        for combo in itertools.product(*chosen):
            sel = dict(zip(others, combo, strict=True))
            tag = f"_{_slice_label(sel)}" if sel else ""
            jobs.append((sel, ds.sel(sel), f"{prefix}_map{tag}.png"))
    for sel, sub, path in jobs:
        good = ok.sel(sel) if sel else ok
        rk = sub["stick_ratio"].where(good)
        rl = sub["contact_loss_ratio"].where(good)
        panels = [("stick ratio $r_k$ (Eq. 26)", rk)]
        if bool((rl.fillna(0) != 0).any()):
            panels.append(("contact-loss ratio $r_l$ (Eq. 27)", rl))
        fig = Figure(figsize=(5.6 * len(panels), 4.4), layout="constrained")
        axes = fig.subplots(1, len(panels), squeeze=False)[0]
        for ax, (label, da) in zip(axes, panels, strict=True):
            if ds.attrs["grid"]["kind"] == "points":
                m = ax.scatter(sub[x].values, sub[y].values, c=da.values, s=30,
                               cmap="viridis", vmin=0.0)
            else:
                m = ax.pcolormesh(sub[y].values, sub[x].values, da.transpose(x, y).values,
                                  shading="nearest", cmap="viridis", vmin=0.0)
                ax.set_xlabel(_axis_label(y))
                ax.set_ylabel(_axis_label(x))
            if ds.attrs["grid"]["kind"] == "points":
                ax.set_xlabel(_axis_label(x))
                ax.set_ylabel(_axis_label(y))
            fig.colorbar(m, ax=ax, label=label)
        held = ", ".join(f"{k} = {v:g} {sweepable().get(k, '')}".rstrip()
                         for k, v in sel.items())
        fig.suptitle(f"{ds.attrs.get('title', 'sweep')}" + (f" at {held}" if held else "")
                     + "\nblank: failed, invalid or not run", fontsize=9)
        fig.savefig(path, dpi=110)
        out.append(Path(path))
    return out
