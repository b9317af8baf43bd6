"""The reference midline of the trace and midline tests, and a writer of its trace files.

The reference shape is a sphere-like meridian with a bulge that keeps it
smooth at the pole (r odd and z even in s): r = sin s (1 + 0.1 cos 3s),
z = 1 − cos s, 0 ≤ s ≤ 0.8π.  Its points equally spaced in arclength come
from Chebyshev quadrature of the exact speed, independently of the package.
Images have R = 50 µm at 0.25 µm per pixel (200 px).
"""
import numpy as np
from numpy.polynomial import Chebyshev

from morphoshell.io import write_trace

S_MAX = 0.8 * np.pi
SCALE = {"pixel_size_um": 0.25, "radius_um": 50.0}
SIGMA = 0.5 * 0.25 / 50.0          # half a pixel, in units of R
SUFFIX = {"csv": ".csv", "xy": ".csv", "fiji-xy": ".txt", "roi": ".roi"}


def shape(s):
    return np.column_stack([np.sin(s) * (1 + 0.1 * np.cos(3 * s)), 1 - np.cos(s)])


def speed(s):
    return np.hypot(np.cos(s) * (1 + 0.1 * np.cos(3 * s)) - 0.3 * np.sin(s) * np.sin(3 * s),
                    np.sin(s))


def truth(n=100):
    """The shape at n points equally spaced in arclength (Newton on a Chebyshev arclength)."""
    arc = Chebyshev.interpolate(speed, 100, domain=[0, S_MAX]).integ(lbnd=0)
    target = np.linspace(0, arc(S_MAX), n)
    s = target / target[-1] * S_MAX
    for _ in range(30):
        s = s - (arc(s) - target) / speed(s)
    return shape(s)


TRUTH = truth()


def half(m=801):
    return shape(np.linspace(0, S_MAX, m))


def write(tmp_path, fmt, name="trace", points=None, **kw):
    path = tmp_path / (name + SUFFIX[fmt])
    scale = {} if fmt == "csv" else SCALE
    write_trace(path, half() if points is None else points, fmt, **scale, **kw)
    return path
