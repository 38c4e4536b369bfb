"""The points of a sweep: one parameter's values, the full factorial of several
(``speed_rpm=5:600:120 torque=1000:4000:7 mu=0.01,0.02,0.03``) or an explicit list of points
from a CSV file (one column per parameter, one row per point).

A `Grid` keeps its shape: a factorial grid has one dimension per parameter (in the order
given), a list of points one dimension ``point``. Points are numbered in C order of that
shape (the last parameter varies fastest); the number is the point's ``index``.
"""

from __future__ import annotations

import csv
import itertools
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .settings import sweepable


def parse_values(text: str) -> list[float]:
    """``"a,b,c"`` or ``"start:stop:num"`` (num evenly spaced values, both ends included)."""
    text = text.strip()
    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise ValueError(f"values {text!r}: use start:stop:num")
        try:
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise ValueError(f"values {text!r}: use start:stop:num with numbers start, stop "
                             "and a whole number num, e.g. 2:600:300") from None
        if n < 1:
            raise ValueError(f"values {text!r}: num must be >= 1")
        return [float(v) for v in np.linspace(a, b, n)]
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"values {text!r}: numbers separated by commas expected") from None


def _check_name(name: str) -> None:
    if name not in sweepable():
        import difflib

        near = difflib.get_close_matches(name, list(sweepable()), n=1)
        hint = f" (did you mean {near[0]}?)" if near else ""
        raise ValueError(f"cannot sweep {name!r}{hint}; choose one of "
                         + ", ".join(sweepable()))


@dataclass(frozen=True)
class Grid:
    """The swept points.

    Attributes
    ----------
    names : the swept parameters (`sweepable` names), in order
    values : for ``kind = "product"`` each parameter's values (the axes); for
        ``kind = "points"`` each parameter's column (one entry per point)
    kind : ``"product"`` (full factorial) or ``"points"`` (an explicit list)
    """

    names: tuple[str, ...]
    values: tuple[tuple[float, ...], ...]
    kind: str = "product"

    def __post_init__(self) -> None:
        if self.kind not in ("product", "points"):
            raise ValueError(f"grid kind {self.kind!r}: product or points")
        if not self.names:
            raise ValueError("empty grid: give at least one parameter")
        for n in self.names:
            _check_name(n)
        dup = {n for n in self.names if self.names.count(n) > 1}
        if dup:
            raise ValueError(f"parameter {sorted(dup)[0]} is given twice")
        if len(self.values) != len(self.names):
            raise ValueError("one list of values per parameter")
        for n, v in zip(self.names, self.values, strict=True):
            if not v:
                raise ValueError(f"empty grid: no values for {n}")
        if self.kind == "points" and len({len(v) for v in self.values}) != 1:
            raise ValueError("every column of a point list needs one value per point")

    @classmethod
    def product(cls, axes: Mapping[str, Any]) -> Grid:
        """Full factorial of ``{name: values}`` (values: a sequence, or text as in
        `parse_values`)."""
        names = tuple(axes)
        vals = tuple(tuple(float(x) for x in (parse_values(v) if isinstance(v, str) else v))
                     for v in axes.values())
        return cls(names, vals, "product")

    @classmethod
    def parse(cls, specs: list[str]) -> Grid:
        """``["speed_rpm=5:600:120", "mu=0.01,0.02"]`` as a factorial grid."""
        axes: dict[str, str] = {}
        for s in specs:
            name, sep, text = s.partition("=")
            name = name.strip()
            if not sep or not name:
                raise ValueError(f"{s!r}: use NAME=VALUES, e.g. speed_rpm=5:600:120 or "
                                 "mu=0.01,0.02")
            if name in axes:
                raise ValueError(f"parameter {name} is given twice")
            _check_name(name)
            axes[name] = text
        return cls.product(axes)

    @classmethod
    def from_csv(cls, path: str | Path) -> Grid:
        """A list of points: a CSV file with a header of parameter names and one row per
        point (``OSError`` for a missing file, ``ValueError`` for bad content)."""
        with Path(path).open(newline="") as fh:
            rows = [r for r in csv.reader(fh) if any(c.strip() for c in r)]
        if not rows:
            raise ValueError(f"--points {path}: empty file; give a header and one row per "
                             "point")
        names = tuple(c.strip() for c in rows[0])
        for n in names:
            _check_name(n)
        cols: list[list[float]] = [[] for _ in names]
        for line, r in enumerate(rows[1:], start=2):
            if len(r) != len(names):
                raise ValueError(f"--points {path}: line {line} has {len(r)} values for "
                                 f"{len(names)} columns")
            for c, x in zip(cols, r, strict=True):
                try:
                    c.append(float(x))
                except ValueError:
                    raise ValueError(f"--points {path}: line {line}: {x.strip()!r} is not a "
                                     "number") from None
        if not cols[0]:
            raise ValueError(f"empty grid: --points {path} has no rows")
        return cls(names, tuple(tuple(c) for c in cols), "points")

    @property
    def dims(self) -> tuple[str, ...]:
        """Dimension names of the stored dataset."""
        return self.names if self.kind == "product" else ("point",)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(v) for v in self.values) if self.kind == "product" \
            else (len(self.values[0]),)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    def point(self, index: int) -> dict[str, float]:
        """The parameter values of point ``index``."""
        if self.kind == "points":
            return {n: v[index] for n, v in zip(self.names, self.values, strict=True)}
        nd = np.unravel_index(index, self.shape)
        return {n: v[k] for n, v, k in zip(self.names, self.values, nd, strict=True)}

    def points(self) -> Iterator[tuple[int, dict[str, float]]]:
        """``(index, {name: value})`` for every point, in index order."""
        if self.kind == "points":
            for i in range(self.size):
                yield i, self.point(i)
            return
        for i, combo in enumerate(itertools.product(*self.values)):
            yield i, dict(zip(self.names, combo, strict=True))

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "names": list(self.names),
                "values": [list(v) for v in self.values]}

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Grid:
        return cls(tuple(d["names"]), tuple(tuple(float(x) for x in v) for v in d["values"]),
                   d["kind"])

    def describe(self) -> str:
        """``speed_rpm (120) x torque (7) = 840 points`` or ``3 points of speed_rpm, mu``."""
        if self.kind == "points":
            return f"{self.size} points of {', '.join(self.names)}"
        axes = " x ".join(f"{n} ({len(v)})" for n, v in zip(self.names, self.values,
                                                             strict=True))
        return f"{axes} = {self.size} points"
