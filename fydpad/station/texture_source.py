"""The texture term of eq. (3) in the render process: any texture family, opened
through the family contract (:mod:`fydpad.texture.family`) for the 1 kHz tick, and the
one speed input every family takes.

The speed is the contact centroid's, differentiated at each camera frame and low-passed
at 10 Hz at the tick rate (Bianchi 2015 III-B): the same value goes to whichever family
renders, and to the output channels' per-block renders.
"""

from __future__ import annotations

from fydpad.errors import UserError
from fydpad.texture.families import load_family
from fydpad.texture.family import TextureFamily
from vision.speed import CentroidSpeed


def tick_speed() -> CentroidSpeed:
    """The station's speed estimator: ``sample(t_s, x_mm, y_mm, contact)`` every tick,
    then ``tick(dt_s)`` gives the speed (mm/s, 0 without contact)."""
    return CentroidSpeed(cutoff_hz=10.0)

def apply_options(family: TextureFamily, spec: str, drive_filter: bool = False,
                  lenient: bool = False) -> None:
    """Set ``--drive-filter`` on a family that has that render parameter (the LPC
    family); on another family it is an error naming the spec, unless ``lenient`` (the
    experiment's stimuli, a mix of families)."""
    if not drive_filter:
        return
    if "drive_filter" in family.parameters:
        family.set_parameter("drive_filter", True)
    elif not lenient:
        raise UserError(f"{spec}: --drive-filter applies to LPC texture models (their "
                        f"'drive_filter' parameter); this one is {family.kind!r}")


def check_texture(spec: str, rate_hz: float, drive_filter: bool = False) -> TextureFamily:
    """Read ``[KIND:]MODEL``, check it ticks at ``rate_hz`` and takes the options: in the
    main process, so a bad model fails in one line before the station starts."""
    family = load_family(spec)
    family.check_rate(rate_hz)
    apply_options(family, spec, drive_filter)
    return family


def open_texture(spec: str, rate_hz: float, drive_filter: bool = False,
                 lenient: bool = False) -> TextureFamily:
    """The family of ``[KIND:]MODEL`` prepared for ``tick`` at ``rate_hz``: everything
    built now, not on the first tick."""
    family = load_family(spec)
    apply_options(family, spec, drive_filter, lenient)
    family.prepare(rate_hz)
    return family
