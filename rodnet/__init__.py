"""rodnet: tether-net simulation with Cosserat rod elements and a lumped-parameter reference."""

import sys as _sys

try:   # a second of imports (numpy, scipy, numba): Ctrl-C there ends with a line, not a traceback
    # before numba starts its threads: how idle threads wait, which threading layer
    # (kernels.threads)
    from rodnet.kernels import threads as _threads

    _threads.configure()

    from rodnet.config import Scene as Scene
    from rodnet.errors import SceneError as SceneError
    from rodnet.errors import SimulationFailed as SimulationFailed
    from rodnet.run import RunResult as RunResult
    from rodnet.run import prepare as prepare
    from rodnet.run import run as run
    from rodnet.scene import load_scene as load_scene
    from rodnet.scene import scene_from_toml as scene_from_toml
except KeyboardInterrupt:
    import os as _os

    print("rodnet: interrupted (Ctrl-C) while loading; nothing was written", file=_sys.stderr,
          flush=True)
    # at once: an interpreter left half-way through numba's imports could end on the signal
    # (status -2) instead of this one
    _os._exit(130)

__version__ = "0.1.0"

# numba's cache is keyed by each kernel's own file only: drop cached kernels built from older
# sources of the modules they use (rodnet.kernels.cache)
from rodnet.kernels.cache import refresh as _refresh_kernel_cache  # noqa: E402

_refresh_kernel_cache()
