r"""Where missing physics can sit: the places a probe extends the physics at, each with the library effects that
extend it there.

========================= =================================================== ======================================
place                     the extension a probe fits                          library effects tried (best scored)
========================= =================================================== ======================================
actuator dynamics         a linear state on the input side                    input_lag
sensor dynamics           a linear state on the output side                   sensor_lag
extra mode                one more linear mode of the device (a pole pair)    extra_mode
output map                a static map of the output, y = h(x, u) (a          quadratic_sensor, magnitude_sensor,
                          calibration curve, a sensor that reads only the     output_saturation, feedthrough, and
                          magnitude, a direct path from the input)            the closed form of the output's
                                                                              residual over the states and inputs
input map                 a static map of the input                           quadratic_input, input_saturation,
                                                                              dead_zone
force                     a force on each degree of freedom, a closed form    the library's forces, and the
                          of its states                                       discovery's closed form where it ran
latent state              a latent state with a small learned rate            latent_state
initial state             is the error at the start, or does it grow?         (the validation records' initial
                                                                              states estimated)
========================= =================================================== ======================================
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FORCE", "INITIAL_STATE", "OUTPUT_MAP", "PLACES", "Place"]


@dataclass(frozen=True)
class Place:
    """A place the missing physics may sit (module docstring): its name, the extension a probe fits there, and the
    library effects that make it (the probe refits the one whose first-order score is highest)."""

    name: str
    extension: str
    effects: tuple[str, ...]


#: The place of a static map of the output: its library effects, and the closed form of the output's residual.
OUTPUT_MAP = "output map"
#: The place of a force on a degree of freedom: the library's forces, and the discovery's closed form.
FORCE = "force"
#: The place that is not an extension: the validation records' initial states.
INITIAL_STATE = "initial state"

#: Every place, in the order that breaks ties between equal gains.
PLACES = (
    Place("actuator dynamics", "a linear state on the input side", ("input_lag",)),
    Place("sensor dynamics", "a linear state on the output side", ("sensor_lag",)),
    Place("extra mode", "one more linear mode (a pole pair)", ("extra_mode",)),
    Place(OUTPUT_MAP, "a static map of the output, y = h(x, u): a calibration curve, a magnitude-only sensor, a "
                        "direct path from the input", ("quadratic_sensor", "magnitude_sensor", "output_saturation",
                                                        "feedthrough")),
    Place("input map", "a static map of the input", ("quadratic_input", "input_saturation", "dead_zone")),
    Place(FORCE, "a force on each degree of freedom, a closed form of its states",
          ("cubic_stiffness", "quadratic_stiffness", "pendulum_restoring", "coulomb_friction", "quadratic_damping",
           "constant_force", "hysteresis", "dynamic_friction")),
    Place("latent state", "a latent state with a small learned rate", ("latent_state",)),
    Place(INITIAL_STATE, "the validation records' initial states estimated: is the error at the start, or does it "
                         "grow (drift)?", ()),
)
