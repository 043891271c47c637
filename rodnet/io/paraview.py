"""The ``paraview.py`` script written beside ``result.pvd``: a ready view of the run in ParaView.

:func:`write_paraview_script` is called by :class:`rodnet.io.vtk.VtkSeries` every time it rewrites
``result.pvd``, so the script always matches the frames written so far (a run stopped early
leaves a valid one). The script opens the series relative to its own location, draws the
threads as tubes coloured by ``tension`` on a colour range fixed to the whole run's tensions,
the bodies as grey surfaces, and points a camera at the run's bounding box. Run as a script
(``pvbatch`` or ``pvpython``) it saves ``paraview.png`` of the last frame beside itself; in the
GUI (``paraview --script=paraview.py``, or Python Shell > Run Script) it only sets up the view.

Facts of ParaView 5.11 the script relies on (checked with Debian's 5.11.0):

- The PVD reader names each top-level block after the ``name`` attribute of its ``DataSet``
  entries, and builds the hierarchy ``/Root/<name>``, where ``<name>`` is the name made a valid
  XML tag (``vtkDataAssembly.MakeValidNodeName``: "SL-8 upper stage" becomes
  ``SL8upperstage``). The blocks come in ``part`` order, so the script selects them by
  position (``/Root/*[1]`` for the threads, ``/Root/*[position() > 1]`` for the bodies), which
  holds for any body name. A series with one part (threads, no bodies) is read as that
  part's grid itself, not as a multi-block: ExtractBlock must not be applied to it (it crashes
  ``pvbatch``).
- ``Tube`` takes polydata only: the threads pass through ``ExtractSurface`` first.
- The GUI runs a script's text without ``__file__`` (and with ``sys.argv == ['']``): the script
  then falls back to the directory it was written in.
- A script run by ``pvbatch``/``pvpython`` has its folder first on ``sys.path``, where a file
  named ``paraview.py`` hides ParaView's own package: the script takes its folder off the path
  before importing ``paraview.simple``.
- ``pvbatch`` on Debian needs an X server (``xvfb-run -a pvbatch paraview.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from string import Template

import numpy as np

SCRIPT_NAME = "paraview.py"
SCREENSHOT_NAME = "paraview.png"
TUBE_FRACTION = 0.002
"""Tube radius as a fraction of the diagonal of the run's bounding box: a thread's physical
radius (0.5 mm) would not show on a net of metres."""

_TEMPLATE = Template('''\
"""ParaView view of the rodnet run in this folder (written by rodnet with result.pvd).

    xvfb-run -a pvbatch paraview.py    # no GUI (Debian's pvbatch needs an X server):
                                       # saves paraview.png of the last frame here
    pvpython paraview.py               # the same, where a display is available
    paraview --script=paraview.py      # the GUI: sets up the view, saves nothing

It may be run from any working directory. rodnet rewrites it with result.pvd after every frame:
the numbers below cover the frames written so far.
"""

import itertools
import math
import os
import sys

WRITTEN_IN = $written_in
"""Where rodnet wrote this script: the GUI runs the script's text without __file__."""
# pvpython and pvbatch run this file as a script; the GUI executes its text, without __file__
AS_SCRIPT = "__file__" in globals()
HERE = os.path.dirname(os.path.abspath(__file__)) if AS_SCRIPT else WRITTEN_IN
# this file is called paraview.py: with its folder on the module path, "import paraview" would
# import this script instead of ParaView's package
sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) not in (HERE, WRITTEN_IN)]

from paraview.simple import (AnnotateTime, ColorBy, ExtractBlock, ExtractSurface,
                             GetActiveViewOrCreate, GetAnimationScene, GetColorTransferFunction,
                             GetOpacityTransferFunction, GetScalarBar, PVDReader, Render,
                             SaveScreenshot, SetActiveSource, Show, Text, Tube)

TENSION_RANGE = $tension_range
"""Smallest and largest axial force [N] over every frame written; every tension is 0 at t = 0,
so ParaView's automatic range (taken from the frame shown) is useless there."""
BOUNDS = $bounds
"""(xmin, xmax, ymin, ymax, zmin, zmax) [m] of the nodes and bodies over every frame."""
TUBE_RADIUS = $tube_radius
"""[m], $tube_percent % of the diagonal of BOUNDS (a thread's own radius would not show)."""
BODIES = $bodies
"""Names of the body blocks (parts 1, 2, ... of result.pvd)."""
FRAMES = $frames
"""Frames written when this script was."""
CAMERA_FITS = "run"
"""What the camera frames: "run", the bounding box of the whole run (playing the series stays
in view), or "frame", the frame shown."""

reader = PVDReader(registrationName="result.pvd", FileName=os.path.join(HERE, "result.pvd"))
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 900]

# with bodies the reader gives a multi-block, its parts in order: threads first, then the
# bodies (whatever their names); with the threads alone it gives their grid itself
threads = ExtractBlock(registrationName="threads", Input=reader,
                       Selectors=["/Root/*[1]"]) if BODIES else reader
surface = ExtractSurface(registrationName="threads as polydata", Input=threads)  # Tube needs it
tubes = Tube(registrationName="tubes", Input=surface)
tubes.Radius = TUBE_RADIUS
tubes.NumberofSides = 12
tubes_shown = Show(tubes, view)
ColorBy(tubes_shown, ("CELLS", "tension"))
lut = GetColorTransferFunction("tension")
lut.ApplyPreset("Viridis (matplotlib)", True)
lut.AutomaticRescaleRangeMode = "Never"  # keep the run's range when the time changes
lut.RescaleTransferFunction(*TENSION_RANGE)
GetOpacityTransferFunction("tension").RescaleTransferFunction(*TENSION_RANGE)
tubes_shown.SetScalarBarVisibility(view, True)
bar = GetScalarBar(lut, view)
bar.Title = "tension [N]"
bar.ComponentTitle = ""
bar.RangeLabelFormat = "%.4g"

if BODIES:
    bodies = ExtractBlock(registrationName="bodies", Input=reader,
                          Selectors=["/Root/*[position() > 1]"])
    bodies_shown = Show(bodies, view)
    bodies_shown.Representation = "Surface"
    bodies_shown.ColorArrayName = ["POINTS", ""]  # solid colour (ColorBy(None) fails in 5.11)
    bodies_shown.AmbientColor = bodies_shown.DiffuseColor = [0.7, 0.7, 0.7]

label = Text(registrationName="about",
             Text="rodnet: %d frame(s), tension %.4g to %.4g N" % ((FRAMES,) + TENSION_RANGE))
label_shown = Show(label, view)
label_shown.WindowLocation = "Upper Right Corner"
label_shown.FontSize = 14
clock = AnnotateTime(registrationName="time", Format="t = {time:.4g} s")
clock_shown = Show(clock, view)
clock_shown.WindowLocation = "Upper Left Corner"
clock_shown.FontSize = 16

times = reader.TimestepValues
times = [times] if isinstance(times, (int, float)) else list(times)  # one frame: a float
animation = GetAnimationScene()
animation.UpdateAnimationUsingDataTimeSteps()
animation.AnimationTime = times[-1]
Render(view)  # paraview.simple resets the camera to the data at the first Render: let it

centre = [0.5 * (BOUNDS[2 * i] + BOUNDS[2 * i + 1]) for i in range(3)]


def camera_distance(direction, up, angle_deg, aspect, margin=1.05):
    """Distance from the centre of BOUNDS, along the unit ``direction`` towards the camera,
    at which all eight corners of BOUNDS are inside the view (vertical angle ``angle_deg``,
    width / height ``aspect``)."""
    right = [up[1] * direction[2] - up[2] * direction[1],
             up[2] * direction[0] - up[0] * direction[2],
             up[0] * direction[1] - up[1] * direction[0]]
    half = math.tan(math.radians(0.5 * angle_deg))
    distance = 0.0
    for corner in itertools.product(*[(BOUNDS[2 * i] - centre[i], BOUNDS[2 * i + 1] - centre[i])
                                      for i in range(3)]):
        depth = sum(c * d for c, d in zip(corner, direction))
        x, y = (abs(sum(c * a for c, a in zip(corner, axis))) for axis in (right, up))
        distance = max(distance, depth + y / half, depth + x / (half * aspect))
    return margin * distance


# look at the whole run's bounding box (so that playing the series stays in view) from
# (1, 1, 1), z up, as rodnet's net.png
toward = [1.0 / math.sqrt(3.0)] * 3
up = [-1.0 / math.sqrt(6.0), -1.0 / math.sqrt(6.0), 2.0 / math.sqrt(6.0)]  # z, made normal to it
distance = max(camera_distance(toward, up, view.CameraViewAngle, 1200 / 900), 1e-6)
view.CameraFocalPoint = centre
view.CameraPosition = [c + distance * d for c, d in zip(centre, toward)]
view.CameraViewUp = up
if CAMERA_FITS == "frame":
    view.ResetCamera(False)  # keeps the direction, fits the data shown

SetActiveSource(tubes)
if AS_SCRIPT:
    SaveScreenshot(os.path.join(HERE, "$screenshot"), view, ImageResolution=[1200, 900])
else:
    Render(view)
''')


def paraview_script(directory: Path, frames: int, tension_range: tuple[float, float],
                    bounds: Sequence[float], body_names: Sequence[str]) -> str:
    """The text of ``paraview.py``.

    Parameters
    ----------
    directory : Path
        Where the script and ``result.pvd`` are; used only when the script runs without
        ``__file__`` (in the GUI).
    frames : int
        Frames written so far.
    tension_range : (2,) float
        Smallest and largest tension [N] over those frames; widened to a range ParaView accepts
        when it is empty (every tension 0, as at t = 0).
    bounds : (6,) float
        ``(xmin, xmax, ymin, ymax, zmin, zmax)`` [m] of everything drawn over those frames.
    body_names : sequence of str
        The body blocks' names, in part order.
    """
    low, high = (float(v) for v in tension_range)
    if not (np.isfinite(low) and np.isfinite(high)):
        low, high = 0.0, 1.0
    if high <= low:  # one value only: ParaView needs low < high
        high = low + max(1.0, abs(low))
    box = np.asarray(bounds, dtype=float)
    if box.shape != (6,) or not np.isfinite(box).all():
        box = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0])
    diagonal = float(np.linalg.norm(box[1::2] - box[0::2]))
    radius = TUBE_FRACTION * diagonal if diagonal > 0.0 else 1e-3
    return _TEMPLATE.substitute(
        tension_range=repr((low, high)), bounds=repr(tuple(float(v) for v in box)),
        tube_radius=repr(radius), tube_percent=f"{100 * TUBE_FRACTION:g}",
        bodies=repr([str(n) for n in body_names]), frames=repr(int(frames)),
        written_in=repr(str(Path(directory).resolve())), screenshot=SCREENSHOT_NAME)


def write_paraview_script(directory: Path, frames: int, tension_range: tuple[float, float],
                          bounds: Sequence[float], body_names: Sequence[str]) -> Path:
    """Write :func:`paraview_script` to ``<directory>/paraview.py`` (atomically: a reader never
    sees half a script) and return its path."""
    path = Path(directory) / SCRIPT_NAME
    tmp = path.with_name(SCRIPT_NAME + ".tmp")
    tmp.write_text(paraview_script(directory, frames, tension_range, bounds, body_names))
    tmp.replace(path)
    return path
