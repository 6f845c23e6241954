"""reeb: contact Hamiltonian splitting integrators for large ensembles of
damped, forced and dissipative systems, on the CPU and the GPU.

    >>> import reeb
    >>> ds = reeb.run({"model": "van_der_pol",
    ...                "params": {"epsilon": {"linspace": [0.1, 3.0, 64]}},
    ...                "initial": {"q": 2.0},
    ...                "integrator": {"scheme": "s2", "dt": 0.01, "steps": 1000},
    ...                "output": {"final": ["q", "s"], "cycle": True}})
    >>> ds.cycle_amplitude.plot()

A scene is a path to a scene file, its TOML text, or a dict with exactly the
TOML's structure. Runs come back as ``xarray.Dataset``: dimensions named
after the scene's axes (then ``frame``, ``point``, ``component``), their
values as coordinates, one data variable per output, the resolved scene
and the run's summary as attributes. ``status`` is 0 for a trajectory that
ran to the end, 1 for one that became non-finite, 2 for one that
``output.stop`` stopped (``status_step``: the step); ``mean_<var>`` and
``resonance`` come with ``output.average`` and ``output.resonance``, the
capture fractions in ``attrs["capture_fractions"]``; ``attractor`` (each
orbit's label) with ``output.attractors``, its table from
``reeb.attractors(ds)``.
"""

from . import dask, report
from ._api import attractors, check, info, open, run, run_options, verify
from ._scene import scene_toml
from .errors import InternalError, ReebError, SceneError
from ._reeb import __version__

__all__ = [
    "run",
    "run_options",
    "open",
    "attractors",
    "check",
    "verify",
    "report",
    "dask",
    "info",
    "scene_toml",
    "ReebError",
    "SceneError",
    "InternalError",
    "__version__",
]
