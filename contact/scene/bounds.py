"""Physical bounds on a scene's magnitudes, and the one tolerance of a frame time.

A scene describes a hand-sized grasp in SI units. A value far outside what such a scene
can mean (a radius of 1e308 m, a modulus of 1e-300 Pa, a gravity of -1e308 m/s^2) is a
typing error, and left alone it overflows somewhere inside numpy or the solver, whose
message names no key. The reader checks each magnitude against these bounds and names
the key (``docs/scene.md`` lists them).
"""

from __future__ import annotations

__all__ = ["BOUNDS", "FRAME_TIME_TOL", "frame_time", "out_of_bounds"]

#: Each kind of magnitude: (least, largest) of its absolute value, and its unit. A length
#: from a hundredth of a millimetre to ten metres; a position or displacement within
#: 100 m of the origin; Young's modulus from 1 Pa (softer than any gel) to 1e12 Pa (above
#: diamond); a density up to 1e5 kg/m^3 (osmium has 2.3e4); a pressure within 1e9 Pa;
#: gravity within 1e3 m/s^2 (a hundred g); a time within 1e9 s.
BOUNDS: dict[str, tuple[float, float, str]] = {
    "length": (1.0e-5, 10.0, "m"),
    "position": (0.0, 100.0, "m"),
    "modulus": (1.0, 1.0e12, "Pa"),
    "density": (0.0, 1.0e5, "kg/m^3"),
    "pressure": (0.0, 1.0e9, "Pa"),
    "acceleration": (0.0, 1.0e3, "m/s^2"),
    "time": (0.0, 1.0e9, "s"),
}
#: Relative tolerance (of the larger of 1 and the time) within which a time given for an
#: automatic flexion is taken as a frame time; the loader then stores that frame time
#: exactly, so that the run's exact match holds.
FRAME_TIME_TOL = 1.0e-9


def out_of_bounds(kind: str, value: float) -> str | None:
    """Why ``value`` lies outside the bounds of ``kind`` (a key of :data:`BOUNDS`), or None.

    Zero passes a kind whose least bound is 0; a nonzero value must reach the least bound.
    """
    lo, hi, unit = BOUNDS[kind]
    a = abs(value)
    if a > hi or (a < lo and not (a == 0.0 and lo == 0.0)):
        what = f"{'an' if kind[0] in 'aeiou' else 'a'} {kind}"
        if lo > 0:
            return f"outside the physical bounds of {what}: {lo:g} to {hi:g} {unit} in size"
        return f"outside the physical bounds of {what}: at most {hi:g} {unit} in size"
    return None


def frame_time(t: float, frames: tuple[float, ...]) -> float | None:
    """The frame time within :data:`FRAME_TIME_TOL` of ``t``, or None.

    Parameters
    ----------
    t : float
    frames : tuple of float

    Returns
    -------
    float or None
        The closest frame time if within the tolerance.
    """
    if not frames:
        return None
    best = min(frames, key=lambda f: abs(f - t))
    return best if abs(best - t) <= FRAME_TIME_TOL * max(1.0, abs(t)) else None
