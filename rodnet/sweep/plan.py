"""Planning a sweep, without dask: the ``--vary`` options, the runs they make (a grid, a Latin
hypercube, or samples times a grid), and the check of every run's scene."""

from __future__ import annotations

import itertools
import json
import tomllib
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from rodnet.config import toml_key
from rodnet.errors import SceneError
from rodnet.scene import ARRAYS, TABLES, canonical_key, scene_from_toml, scene_text


@dataclass(frozen=True)
class Vary:
    """One ``--vary``: a key with a list of values (``values``, TOML text each) or a range
    ``[low, high]`` sampled by the Latin hypercube (``integer``: the key takes integers)."""

    key: str
    values: tuple[str, ...] = ()
    low: float = 0.0
    high: float = 0.0
    integer: bool = False

    @property
    def sampled(self) -> bool:
        return not self.values


@dataclass(frozen=True)
class Run:
    """One run of a sweep: its index and the value of every varied key, in ``--vary`` order."""

    index: int
    values: tuple[tuple[str, Any], ...]

    @property
    def overrides(self) -> list[str]:
        """The ``KEY=VALUE`` overrides of this run (after the sweep's ``--set``)."""
        return [f"{key}={_toml(value)}" for key, value in self.values]

    @property
    def folder(self) -> str:
        return f"runs/{self.index:04d}"


@dataclass(frozen=True)
class Sweep:
    """A planned sweep: the scene, the command's options and the runs they make."""

    scene_path: Path
    text: str
    vary: tuple[str, ...]
    sets: tuple[str, ...]
    samples: int | None
    seed: int | None
    runs: tuple[Run, ...]

    @property
    def keys(self) -> list[str]:
        """The varied keys, in ``--vary`` order."""
        return [key for key, _ in self.runs[0].values]

    def definition(self) -> dict[str, Any]:
        """What ``sweep.json`` says of the sweep (besides the versions that ran it)."""
        return {"scene": {"path": str(self.scene_path), "text": self.text},
                "vary": list(self.vary), "set": list(self.sets), "samples": self.samples,
                "seed": self.seed, "runs": [{"index": r.index, "folder": r.folder,
                                             "overrides": r.overrides} for r in self.runs]}

    def overrides(self, run: Run) -> list[str]:
        """Every override of ``run``: the sweep's ``--set``, then its varied keys."""
        return [*self.sets, *run.overrides]


# --- planning (no dask) -------------------------------------------------------------------


def plan(scene_path: str | Path, vary: Sequence[str], sets: Sequence[str] = (),
         samples: int | None = None, seed: int | None = None) -> Sweep:
    """Read the scene, parse the options, make the runs and check every one of them.

    Parameters
    ----------
    scene_path : str or Path
        The scene file.
    vary : sequence of str
        ``KEY=V1,V2,...`` (a grid axis; values in TOML syntax, as ``--set`` reads them) or
        ``KEY=LOW:HIGH`` (a range of the Latin hypercube).
    sets : sequence of str
        ``KEY=VALUE`` overrides of every run, as ``rodnet run --set``.
    samples, seed : int, optional
        Latin-hypercube samples of the ranges (required with a range) and the generator's seed
        (None: a new draw each time; ``rodnet sweep`` gives 0, so the same command resumes).
        The runs are every sample combined with every point of the grid, samples outermost.

    Raises
    ------
    SceneError
        A bad option, or a run whose scene ``rodnet run`` would refuse (the message says which
        run).
    """
    path = Path(scene_path)
    text = scene_text(path)
    if not vary:
        raise SceneError("--vary", None, "give at least one --vary KEY=V1,V2,... or KEY=LOW:HIGH")
    axes = [parse_vary(item) for item in vary]
    keys = [a.key for a in axes]
    repeated = next((k for k in keys if keys.count(k) > 1), None)
    if repeated:
        raise SceneError("--vary", repeated, "each key may be varied once")
    fixed = {canonical_key(s.partition("=")[0]) for s in sets}
    if "output.directory" in fixed | set(keys):
        raise SceneError("--vary" if "output.directory" in keys else "--set", "output.directory",
                         "is the sweep's to choose: every run writes to runs/NNNN of -o")
    if fixed & set(keys):
        key = sorted(fixed & set(keys))[0]
        raise SceneError("--set", key, "is also varied (--vary): set it or vary it, not both")
    runs = _runs(axes, samples, seed)
    sweep = Sweep(path.resolve(), text, tuple(vary), tuple(sets), samples,
                  seed if samples is not None else None, runs)
    check(sweep)
    return sweep


def parse_vary(item: str) -> Vary:
    """``KEY=V1,V2,...`` or ``KEY=LOW:HIGH`` -> :class:`Vary` (:class:`SceneError` if neither)."""
    key, sep, raw = item.partition("=")
    key = canonical_key(key)   # one spelling: a key varied twice is told, whatever the spelling
    if not sep or not key or not raw.strip():
        raise SceneError("--vary", item, "must look like KEY=V1,V2,... or KEY=LOW:HIGH")
    parts = _split(raw)
    if len(parts) == 1 and ":" in raw and not raw.strip().startswith(("[", '"', "'")):
        low, high = (_number(p) for p in raw.split(":", 1))
        if low is None or high is None or not low < high:
            raise SceneError("--vary", item, "a range must be LOW:HIGH, two numbers with LOW < HIGH")
        return Vary(key, low=float(low), high=float(high), integer=_takes_integers(key))
    if any(not p for p in parts):
        raise SceneError("--vary", item, "has an empty value: V1,V2,... separated by commas")
    values = [_value(p) for p in parts]
    repeated = next((p for i, p in enumerate(parts) if values[i] in values[:i]), None)
    if repeated is not None:   # the same run twice (15 and 15.0 alike)
        raise SceneError("--vary", item, f"gives the value {repeated} twice: each value once")
    return Vary(key, values=tuple(parts))


def by_value(items: Any, split: bool) -> Any:
    """``KEY=VALUE`` options (``--vary``: ``KEY=V1,V2,...``) as ``[key, values]`` with the key in
    one spelling and the values as ``--set`` reads them; anything else as it is."""
    if not isinstance(items, list) or not all(isinstance(i, str) for i in items):
        return items
    out = []
    for item in items:
        key, _, raw = item.partition("=")
        parts = _split(raw) if split else [raw]
        out.append([canonical_key(key), [_value(part) for part in parts]])
    return out


def _split(raw: str) -> list[str]:
    """``raw`` split at the commas outside brackets, braces and quotes, each part stripped."""
    parts, depth, quote, start = [], 0, "", 0
    for i, c in enumerate(raw):
        if quote:
            quote = "" if c == quote else quote
        elif c in "\"'":
            quote = c
        elif c in "[{":
            depth += 1
        elif c in "]}":
            depth -= 1
        elif c == "," and depth == 0:
            parts.append(raw[start:i].strip())
            start = i + 1
    return parts + [raw[start:].strip()]


def _value(raw: str) -> Any:
    """A value as ``--set`` reads it: TOML, or the bare text as a string."""
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw.strip()


def _number(raw: str) -> float | None:
    value = _value(raw)
    return value if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _toml(value: Any) -> str:
    """``value`` in the TOML syntax of an override."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def _takes_integers(key: str) -> bool:
    """Whether scene key ``key`` (``section.key`` or ``section[i].key``) is an integer key."""
    section, _, name = key.replace("]", "").partition(".")
    cls = TABLES.get(section.split("[")[0]) or ARRAYS.get(section.split("[")[0])
    if cls is None:
        return False
    hints = typing.get_type_hints(cls)
    field = next((f for f in hints if toml_key(f) == name), None)
    return field is not None and int in (hints[field], *typing.get_args(hints[field]))


def _runs(axes: list[Vary], samples: int | None, seed: int | None) -> tuple[Run, ...]:
    """Every Latin-hypercube sample of the ranges times every point of the grid."""
    ranged = [a for a in axes if a.sampled]
    if ranged and samples is None:
        raise SceneError("--vary", f"{ranged[0].key}={ranged[0].low:g}:{ranged[0].high:g}",
                         "a range LOW:HIGH needs --samples N (the Latin-hypercube samples)")
    if samples is not None and not ranged:
        raise SceneError("--samples", samples, "samples ranges: give a --vary KEY=LOW:HIGH")
    points: list[dict[str, Any]] = [{}]
    if ranged:
        from scipy.stats import qmc

        unit = qmc.LatinHypercube(d=len(ranged), seed=seed).random(samples)
        low = [a.low for a in ranged]
        high = [a.high + (1.0 if a.integer else 0.0) for a in ranged]
        scaled = qmc.scale(unit, low, high)
        points = [{a.key: (min(int(x // 1), int(a.high)) if a.integer else float(x))
                   for a, x in zip(ranged, row)} for row in scaled]
    grid = [a for a in axes if not a.sampled]
    combos = list(itertools.product(*[[_value(v) for v in a.values] for a in grid]))
    runs = []
    for point in points:
        for combo in combos:
            values = {**point, **dict(zip((a.key for a in grid), combo))}
            runs.append(Run(len(runs), tuple((a.key, values[a.key]) for a in axes)))
    return tuple(runs)


def check(sweep: Sweep) -> None:
    """Build and prepare every run's scene as ``rodnet run`` does (:func:`rodnet.run.prepare`);
    a refusal names the run and its varied values."""
    from rodnet.run import prepare

    for run in sweep.runs:
        try:
            prepare(scene_from_toml(sweep.text, sweep.overrides(run), source=str(sweep.scene_path)))
        except SceneError as exc:
            raise SceneError(exc.key, exc.value, f"{exc.allowed} (in run {run.index} of the "
                             f"sweep: {', '.join(run.overrides)})") from None
