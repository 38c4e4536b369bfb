"""A finished sweep in memory (`SweepResult`) and its one-parameter files: CSV, Poincare CSV,
JSON summary (and PNG through `plot`), with their readers."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .point import COLUMNS
from .settings import SweepSettings, sweepable


# -- the sweep --------------------------------------------------------------------------------
@dataclass
class SweepResult:
    """All points of a sweep (sorted by index, failed ones included) and its cost.

    Attributes
    ----------
    name : swept parameter; values : its values; settings : the held settings
    records : one dict per point (`COLUMNS` plus ``poincare``)
    elapsed_s : wall time of the computation (submission to last result), s
    startup_s : wall time to start or reach the cluster and warm the compiled code, s
    workers : number of worker threads used; scheduler : ``local``, ``serial`` or an address
    """

    name: str
    values: list[float]
    settings: SweepSettings
    records: list[dict[str, Any]]
    elapsed_s: float = 0.0
    startup_s: float = 0.0
    workers: int = 1
    scheduler: str = "serial"
    retried: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def failed(self) -> list[dict[str, Any]]:
        """Points that did not run to the end (``status = failed``)."""
        return [r for r in self.records if r["status"] == "failed"]

    @property
    def invalid(self) -> list[dict[str, Any]]:
        """Points refused by the validation or outside the model (``status = invalid``)."""
        return [r for r in self.records if r["status"] == "invalid"]

    @property
    def throughput(self) -> float:
        """Points per second of wall time over the computation (startup excluded)."""
        return len(self.records) / self.elapsed_s if self.elapsed_s > 0 else math.nan

    def column(self, name: str) -> np.ndarray:
        """A numeric column over all points (NaN for failed points)."""
        return np.array([float(r[name]) for r in self.records])

    def summary(self) -> dict[str, Any]:
        busy = float(sum(r["wall_s"] for r in self.records))
        cpu = float(np.nansum([r.get("cpu_s", math.nan) for r in self.records]))
        return {
            "param": self.name, "unit": sweepable().get(self.name, ""),
            "points": len(self.records),
            "ok": sum(r["status"] == "ok" for r in self.records),
            "failed": [{"index": r["index"], "value": r["value"], "error": r["error"]}
                       for r in self.failed],
            "invalid": [{"index": r["index"], "value": r["value"], "error": r["error"]}
                        for r in self.invalid],
            "retried": self.retried, "scheduler": self.scheduler, "workers": self.workers,
            "startup_s": round(self.startup_s, 3), "elapsed_s": round(self.elapsed_s, 3),
            "total_s": round(self.startup_s + self.elapsed_s, 3),
            "throughput_points_per_s": round(self.throughput, 4),
            "point_busy_s": round(busy, 3), "point_cpu_s": round(cpu, 3),
            "efficiency": round(busy / (self.workers * self.elapsed_s), 3)
            if self.elapsed_s > 0 else None,
            "cpu_share": round(cpu / busy, 3) if busy > 0 else None,
            "settings": asdict(self.settings), **self.extra,
        }

    def report(self) -> str:
        """One line with the counts and the throughput."""
        s = self.summary()
        line = (f"sweep {self.name}: {s['points']} points ({s['ok']} ok, {len(s['failed'])} "
                f"failed, {len(s['invalid'])} invalid, {s['retried']} retried) in "
                f"{s['elapsed_s']:.1f} s on {self.workers} "
                f"worker(s) [{self.scheduler}]: {s['throughput_points_per_s']:.3f} points/s; "
                f"startup {s['startup_s']:.1f} s; efficiency {s['efficiency']}; the points got "
                f"{s['cpu_share']} of a core while running")
        for f in s["failed"]:
            line += f"\n  FAILED point {f['index']} ({self.name} = {f['value']}): {f['error']}"
        for f in s["invalid"]:
            line += f"\n  INVALID point {f['index']} ({self.name} = {f['value']}): {f['error']}"
        return line

    def to_csv(self, path: str | Path) -> Path:
        """One row per point, the `COLUMNS` (failed points included, with their error)."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow(COLUMNS)
            for r in self.records:
                wr.writerow([_fmt(r.get(c, math.nan)) for c in COLUMNS])
        return path

    def poincare_to_csv(self, path: str | Path) -> Path:
        """The bifurcation data: ``index, value, k, dte_um`` for every Poincare sample."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow(("index", "value", "k", "dte_um"))
            for r in self.records:
                for k, x in enumerate(r["poincare"]):
                    wr.writerow((r["index"], _fmt(r["value"]), k, f"{x * 1e6:.9g}"))
        return path

    def write(self, prefix: str | Path, plot: bool = True) -> dict[str, str]:
        """Write ``PREFIX.csv``, ``PREFIX_poincare.csv``, ``PREFIX.json`` (summary) and,
        with ``plot``, ``PREFIX.png``; returns the paths."""
        prefix = Path(prefix)
        prefix.parent.mkdir(parents=True, exist_ok=True)
        out = {"csv": str(self.to_csv(prefix.with_suffix(".csv"))),
               "poincare": str(self.poincare_to_csv(Path(f"{prefix}_poincare.csv")))}
        js = prefix.with_suffix(".json")
        js.write_text(json.dumps(self.summary(), indent=2, default=str))
        out["json"] = str(js)
        if plot:
            from .plot import plot_sweep  # matplotlib loads only to draw

            out["png"] = str(plot_sweep(self, prefix.with_suffix(".png")))
        return out


def read_result(prefix: str | Path) -> SweepResult:
    """A `SweepResult` back from the files `SweepResult.write` made (``PREFIX.csv``,
    ``PREFIX_poincare.csv``, ``PREFIX.json``)."""
    prefix = Path(prefix)
    summ = json.loads(prefix.with_suffix(".json").read_text())
    recs = read_csv(prefix.with_suffix(".csv"))
    samples: dict[int, list[float]] = {int(r["index"]): [] for r in recs}
    with Path(f"{prefix}_poincare.csv").open(newline="") as fh:
        for row in csv.DictReader(fh):
            samples[int(row["index"])].append(float(row["dte_um"]) * 1e-6)
    for r in recs:
        r["index"] = int(r["index"])
        r["poincare"] = samples[r["index"]]
    st = dict(summ["settings"])
    st["params"] = tuple(tuple(x) for x in st.get("params", ()))
    return SweepResult(summ["param"], [float(r["value"]) for r in recs], SweepSettings(**st),
                       recs, summ["elapsed_s"], summ["startup_s"], summ["workers"],
                       summ["scheduler"], summ["retried"])


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return "" if math.isnan(x) else f"{x:.10g}"
    return str(x)


def read_csv(path: str | Path) -> list[dict[str, Any]]:
    """Read a sweep CSV back (numbers as float, empty cells as NaN)."""
    with Path(path).open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for r in rows:
        d: dict[str, Any] = {}
        for k, v in r.items():
            if k in ("param", "status", "error", "friction", "stick_tie", "sliding", "worker"):
                d[k] = v
            else:
                d[k] = float(v) if v != "" else math.nan
        out.append(d)
    return out


def read_poincare_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read ``PREFIX_poincare.csv``: (values, dte_um) arrays, one entry per sample."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    return np.atleast_1d(data["value"]), np.atleast_1d(data["dte_um"])


