"""The work-precision diagram."""

from __future__ import annotations

from pathlib import Path

from .report import describe, regimes_of
from .settings import TARGET_ERROR


def plot(result: dict, path: str | Path, clock: str = "wall") -> None:
    """Work-precision diagram: error against time per simulated second (log-log; ``clock``
    "wall" or "cpu"), DTE (top) and mesh force (bottom), one panel per regime, one line per
    method."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError("--plot needs matplotlib: pip install 'gearpair[plot]'") from None
    regimes = regimes_of(result)
    fig = Figure(figsize=(4.4 * len(regimes), 7.5), layout="constrained")
    ax = fig.subplots(2, len(regimes), sharex=True, sharey="row", squeeze=False)
    from matplotlib import colormaps

    tab20 = colormaps["tab20"]
    for a in ax.flat:  # a dozen lines: more colours than the default ten
        a.set_prop_cycle(color=[tab20(i) for i in (0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 1, 3, 5,
                                                   7, 9, 11)])
    markers = {"fast": "o", "fast dp5": "x", "RK45": "s", "DOP853": "D", "Radau": "^",
               "LSODA": "v", "FMU": "*", "plain": "P"}  # by the method, else its first word
    rows = result["work_precision"]
    for j, regime in enumerate(regimes):
        mine = [r for r in rows if r["regime"] == regime]
        lines: dict[str, list[dict]] = {}
        for r in mine:
            key = r["method"] if r["method"] != "FMU" else f"FMU rtol {r['rtol']:g}"
            lines.setdefault(key, []).append(r)
        for i, err in enumerate(("err_dte", "err_force")):
            a = ax[i, j]
            for key, rs in lines.items():
                # along the setting: loose to tight tolerance, coarse to fine FMU step
                rs = sorted((r for r in rs if not r["error"]),
                            key=lambda r: (-r["step"], -r["rtol"]) if key.startswith("FMU")
                            else (-r["rtol"], -r["step"]))
                x = [r[f"{clock}_per_sim_s"] for r in rs]
                y = [max(r[err], 1e-16) for r in rs]
                a.loglog(x, y, marker=markers.get(key, markers.get(key.split()[0], "o")),
                         ms=4, lw=1, label=key)
                if key.startswith("FMU"):
                    for r, xx, yy in zip(rs, x, y, strict=True):
                        a.annotate(f"h={r['step']:g}", (xx, yy), fontsize=6,
                                   textcoords="offset points", xytext=(3, 3))
            a.axhline(TARGET_ERROR, color="0.5", lw=0.8, ls="--")
            a.grid(True, which="both", lw=0.3)
            if i == 0:
                a.set_title(f"{regime}\n({describe(regime)})", fontsize="medium")
            else:
                a.set_xlabel(f"{'CPU' if clock == 'cpu' else 'wall'} time per simulated "
                             "second (s)")
        ax[0, j].legend(fontsize="x-small", ncols=2)
    ax[0, 0].set_ylabel("DTE error (relative)")
    ax[1, 0].set_ylabel("mesh force error (relative)")
    m = result["machine"]
    fig.suptitle(f"gearpair work-precision, {m['cpu']} ({m['cores']} cores), "
                 f"{m['date'][:10]}")
    fig.savefig(Path(path), dpi=120)

