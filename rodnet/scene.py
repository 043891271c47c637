"""Load a scene from TOML into the frozen dataclasses of :mod:`rodnet.config`.

Dicts exist only here. Parsing is strict: an unknown key or section, a wrong type or an
out-of-range value raises :class:`SceneError` naming the key (with its section), the value and
what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, Literal

from rodnet.config import (BodySpec, ContactSpec, InitialSpec, LineLoadSpec, LoadSpec, MassSpec,
                           MaterialSpec, ModelSpec, NetSpec, OutputSpec, RodSpec, Scene,
                           SimulationSpec, SupportSpec, toml_key)
from rodnet.errors import SceneError

TABLES = {"simulation": SimulationSpec, "model": ModelSpec, "net": NetSpec,
          "contact": ContactSpec, "initial": InitialSpec, "output": OutputSpec}
ARRAYS = {"materials": MaterialSpec, "rods": RodSpec, "supports": SupportSpec,
          "loads": LoadSpec, "line_loads": LineLoadSpec, "masses": MassSpec,
          "bodies": BodySpec}
NOT_YET: dict[str, str] = {}
"""Sections of SCENE_FORMAT.md this version refuses (section -> what it describes)."""


def load_scene(path: str | Path, overrides: typing.Sequence[str] = ()) -> Scene:
    """Read a TOML scene file and apply ``KEY=VALUE`` overrides.

    Parameters
    ----------
    path : str or Path
        The scene file.
    overrides : sequence of str
        ``"section.key=value"`` (value in TOML syntax; a bare word is taken as a string),
        ``"materials[0].density=1500"`` for array sections.
    """
    return scene_from_toml(scene_text(path), overrides, source=str(path))


def scene_text(path: str | Path) -> str:
    """The text of the scene file ``path``; :class:`SceneError` when it cannot be read."""
    path = Path(path)
    try:
        return path.read_text()
    except OSError as exc:
        raise SceneError("", str(path), f"cannot read the scene file {path}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise SceneError("", str(path), f"the scene file {path} is not a text (TOML) file") from None


def scene_from_toml(text: str, overrides: typing.Sequence[str] = (), source: str = "<scene>") -> Scene:
    """Like :func:`load_scene`, from TOML text; ``source`` names it in messages."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("", source, f"the scene {source} is not valid TOML: {exc}") from None
    return scene_from_dict(apply_overrides(data, overrides), source=source)


def key_parts(key: str) -> list[str]:
    """The names and indexes of a scene key as ``--set`` reads it: ``materials.0.viscosity``
    and ``materials[0].viscosity`` both give ``["materials", "0", "viscosity"]``."""
    return key.strip().replace("[", ".").replace("]", "").split(".")


def canonical_key(key: str) -> str:
    """A scene key in one spelling (:func:`key_parts`): ``materials.0.viscosity`` as
    ``materials[0].viscosity``."""
    out = ""
    for part in key_parts(key):
        out += (f"[{part}]" if part.isdigit() else f".{part}") if out else part
    return out


def apply_overrides(data: dict[str, Any], overrides: typing.Sequence[str]) -> dict[str, Any]:
    """Return a copy of ``data`` with every ``KEY=VALUE`` override set."""
    import copy

    data = copy.deepcopy(data)
    for item in overrides:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise SceneError("--set", item, "must look like section.key=value")
        parts = key_parts(key)
        try:
            value = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        node: Any = data
        for i, part in enumerate(parts[:-1]):
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise SceneError("--set", item, f"the index [{part}] of {parts[i - 1]} must "
                                     f"be an integer 0..{len(node) - 1} in this scene")
                node = node[int(part)]
            else:
                if parts[i + 1].isdigit() and not isinstance(node.get(part), list):
                    raise SceneError(key, value, f"indexes [[{part}]], which this scene does "
                                     "not have: add the table to the scene file")
                node = node.setdefault(part, {})
        if isinstance(node, list):
            raise SceneError(key, value, f"names an array of tables: give the entry's index, "
                             f"as in {'.'.join(parts[:-1])}[0].{parts[-1]}")
        if not isinstance(node, dict):
            raise SceneError(key, value, "names no table of the scene")
        node[parts[-1]] = value
    return data


def scene_from_dict(data: dict[str, Any], source: str = "<scene>") -> Scene:
    """Build a :class:`Scene` from parsed TOML."""
    kwargs: dict[str, Any] = {"source": source}
    for name, value in data.items():
        if name in TABLES:
            _expect(isinstance(value, dict), name, value, "must be a table [name]")
            kwargs[name] = _build(TABLES[name], value, name)
        elif name in ARRAYS:
            _expect(isinstance(value, list) and all(isinstance(v, dict) for v in value), name,
                    value, f"must be an array of tables [[{name}]]")
            kwargs[name] = tuple(_build(ARRAYS[name], v, f"{name}[{i}]") for i, v in enumerate(value))
        elif name in NOT_YET:
            raise SceneError(name, "...", f"{NOT_YET[name]} are not supported by this version of rodnet")
        else:
            raise SceneError(name, value if not isinstance(value, dict) else "{...}",
                             f"unknown section; allowed: {sorted([*TABLES, *ARRAYS])}")
    return Scene(**kwargs)


def _expect(ok: bool, key: str, value: Any, allowed: str) -> None:
    if not ok:
        raise SceneError(key, value, allowed)


def _build(cls: type, table: dict[str, Any], path: str) -> Any:
    """Instantiate dataclass ``cls`` from ``table``, checking keys and types."""
    hints = typing.get_type_hints(cls)
    fields = {toml_key(f.name): f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in table.items():
        if key not in fields:
            raise SceneError(f"{path}.{key}", value, f"unknown key in [{path.split('[')[0]}]; "
                             f"allowed: {sorted(fields)}")
        name = fields[key].name
        kwargs[name] = _convert(hints[name], value, f"{path}.{key}")
    missing = [n for n, f in fields.items() if f.default is dataclasses.MISSING
               and f.default_factory is dataclasses.MISSING and f.name not in kwargs]
    if missing:
        raise SceneError(f"{path}.{missing[0]}", None, "is required")
    try:
        return cls(**kwargs)
    except SceneError as exc:
        raise exc.within(path) from None


def _convert(hint: Any, value: Any, key: str) -> Any:
    """Check ``value`` against type ``hint`` and convert it (int to float, list to tuple)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None:
            return None
        return _convert(next(a for a in args if a is not type(None)), value, key)
    if origin is Literal:
        _expect(value in args, key, value, f"must be one of {list(args)}")
        return value
    if hint is bool:
        _expect(isinstance(value, bool), key, value, "must be true or false")
        return value
    if hint is int:
        _expect(isinstance(value, int) and not isinstance(value, bool), key, value,
                "must be an integer")
        return value
    if hint is float:
        _expect(isinstance(value, (int, float)) and not isinstance(value, bool), key, value,
                "must be a number")
        _expect(math.isfinite(value), key, value, "must be a finite number")
        return float(value)
    if hint is str:
        _expect(isinstance(value, str), key, value, "must be a string")
        return value
    if origin is tuple:
        fixed = not (len(args) == 2 and args[1] is Ellipsis)
        _expect(isinstance(value, list), key, value,
                f"must be an array of {len(args)} numbers" if fixed else "must be an array")
        if not fixed:
            return tuple(_convert(args[0], v, f"{key}[{i}]") for i, v in enumerate(value))
        _expect(len(value) == len(args), key, value, f"must be an array of {len(args)} numbers")
        return tuple(_convert(a, v, f"{key}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    raise TypeError(f"no converter for {hint!r}")  # a programming error, not bad input
