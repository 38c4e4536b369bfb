"""Scene files: one TOML file says what to simulate, and only that.

A scene holds the gear data, the effects the run calls for, the operating inputs (torque and
speed as constants, ramps, steps or a CSV time series), the solver settings and the outputs.
`load_scene` reads and validates it into frozen objects; `Scene.run` simulates it with the
fast or reference engine or through the FMU. ``docs/scenes.md`` is the format reference.

Everything inside is SI. Keys whose unit is not SI say so in their name (``speed_rpm``,
``pressure_angle_deg``). Every error names the key (``[gear] m1 = -3 is out of range; ...``),
and relative file names are resolved against the scene file's folder.

The package: `types` (the scene and its sections, `Scene.run`), `reading` (TOML into a
validated scene), `fmu` (the FMU as an engine: start values, the fmpy run), `location`
(where the FMU is, and whether it is stale) and `errors`.
"""

from .errors import SceneError, SceneWarning
from .fmu import fmu_start_values, run_fmu
from .location import find_fmu, stale_reason
from .reading import load_scene, parse_scene
from .types import (
    ENGINES,
    OUTPUT_NAMES,
    STEP_MAX,
    STEP_MIN,
    T_END_MAX,
    Inputs,
    OutputSpec,
    Scene,
    Solver,
)

__all__ = ["ENGINES", "OUTPUT_NAMES", "STEP_MAX", "STEP_MIN", "T_END_MAX", "Inputs",
           "OutputSpec", "Scene", "SceneError", "SceneWarning", "Solver", "find_fmu",
           "fmu_start_values", "stale_reason", "load_scene", "parse_scene", "run_fmu"]
