"""The shape of a ``[[bodies]]`` entry: a primitive (:mod:`rodnet.contact.geometry`) or a
triangle mesh read from a file (:mod:`rodnet.contact.mesh`)."""

from __future__ import annotations

from pathlib import Path

from rodnet.contact.geometry import Box, Cylinder, Shape, Sphere, positive_length
from rodnet.contact.mesh import load_mesh
from rodnet.errors import SceneError


def shape_from_scene(shape: str, size: tuple[float, float, float] | None = None,
                     file: str | Path | None = None, base_dir: str | Path = ".",
                     ) -> Shape:
    """The shape of a ``[[bodies]]`` entry (SCENE_FORMAT.md): keys ``shape``, ``size``, ``file``.

    ``size`` is the edge lengths of a box, ``[d, d, length]`` of a cylinder (axis along body z)
    and ``[d, d, d]`` of a sphere; a mesh is read from ``file`` relative to ``base_dir`` and
    centred on its centre of volume.
    """
    if shape == "mesh":
        if file is None:
            raise SceneError("file", None, "is required for shape = \"mesh\"")
        return load_mesh(Path(base_dir) / file)[0]
    if shape not in ("box", "cylinder", "sphere"):
        raise SceneError("shape", shape, "must be \"box\", \"cylinder\", \"sphere\" or \"mesh\"")
    if size is None or len(size) != 3:
        raise SceneError("size", size, "must be three lengths [m]")
    for v in size:
        positive_length("size", v)
    if shape == "box":
        return Box(tuple(0.5 * float(v) for v in size))
    if shape == "cylinder":
        if size[0] != size[1]:
            raise SceneError("size", size, "a cylinder is [diameter, diameter, length]")
        return Cylinder(0.5 * size[0], float(size[2]), axis=2)
    if not size[0] == size[1] == size[2]:
        raise SceneError("size", size, "a sphere is [diameter, diameter, diameter]")
    return Sphere(0.5 * size[0])
