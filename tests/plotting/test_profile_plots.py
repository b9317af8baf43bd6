"""Profile panels (:mod:`morphoshell.plotting.profiles`): drawn in the package's colours."""
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import to_hex

from morphoshell.fitting import Profile
from morphoshell.plotting import OKABE_ITO, plot_profile


def _profile():
    """A profile whose last refit did not converge (every element of the panel drawn)."""
    x = np.linspace(-1.0, 1.0, 5)
    return Profile("kappa1", 0.0, x, 1 + x ** 2, np.array([True] * 4 + [False]), (-0.5, 0.5),
                   2.0, 1.0, 0.1, "traces", 0.95, False, "gradient")


def test_profile_is_drawn_in_okabe_ito_colours():
    # the refits, the unconverged one and the interval were tab10's C0, C3 and C1 (blue,
    # red, orange), which readers with red-green colour blindness confuse
    fig, ax = plt.subplots()
    plot_profile(_profile(), ax)
    lines = {line.get_label(): to_hex(line.get_color()) for line in ax.lines}
    assert lines["refit"] == OKABE_ITO["blue"].lower()
    assert lines["not converged"] == OKABE_ITO["vermillion"].lower()
    (span,) = ax.patches
    assert to_hex(span.get_facecolor()) == OKABE_ITO["orange"].lower()
    plt.close(fig)
