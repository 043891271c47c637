"""The child process of :func:`rodnet.viz.figures.render_in_subprocess`: draws the pictures
and the movie of an output folder, one task after the other, so that pyvista and the OpenGL
stack start once for all of them.

``python -m rodnet.viz.worker DIR [--picture] [--plot] [--movie]``. After each task the child
prints ``done TASK`` on standard output; a task that raises prints ``TASK failed: message`` on
standard error and the child goes on with the next one (exit status 1 at the end). A crash of
the process (of the OpenGL stack, say) leaves the tasks not yet done unreported.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Callable

from rodnet.viz.figures import picture_at_max_area, plot_deployment
from rodnet.viz.movie import movie_after_run

TASKS: dict[str, Callable[[Path], Path]] = {
    "picture": picture_at_max_area, "plot": plot_deployment, "movie": movie_after_run}
"""What each task writes: ``net.png``, ``deployment.png``, ``deployment.mp4`` (of every second
saved frame)."""


def main(argv: list[str]) -> int:
    """Run the tasks ``--NAME`` of ``argv`` on the folder ``argv[0]``; 0 when all were done."""
    directory, failed = Path(argv[0]), False
    for name in (a[2:] for a in argv[1:]):
        try:
            TASKS[name](directory)
        except Exception as exc:  # reported to the parent, which turns it into a warning
            print(f"{name} failed: {type(exc).__name__}: {exc}".replace("\n", " "),
                  file=sys.stderr, flush=True)
            failed = True
        else:
            print(f"done {name}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
