"""The profile figure numbers pings from 0, like the peaks tables and image files."""

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from clbeam.seabed.profile import profile_figure

N_PING, N_ROWS, BRIGHT = 7, 50, 4


def drawn(distance=None):
    env = np.full((N_PING, N_ROWS), 1e-3)
    env[BRIGHT, 20] = 1.0  # one bright sample in ping BRIGHT
    fig = profile_figure(env, t_top_s=0.0, t_bottom_s=0.05, sound_speed_m_s=1500.0, along_track_distance_m=distance)
    FigureCanvasAgg(fig).draw()
    return fig.axes[0]


def test_ping_i_is_drawn_centred_on_i_and_the_axis_starts_at_0():
    ax = drawn()
    x0, x1, _, _ = ax.images[0].get_extent()
    width = (x1 - x0) / N_PING
    column = int(np.argmax(ax.images[0].get_array().max(axis=0)))  # the image is (row, ping)
    assert column == BRIGHT and x0 + (column + 0.5) * width == pytest.approx(BRIGHT)
    ticks = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
    assert ticks[0] == 0 and ticks[-1] == N_PING - 1 and all(float(t).is_integer() for t in ticks)


def test_the_along_track_axis_puts_each_pings_distance_over_its_number():
    d = np.cumsum(np.r_[0.0, np.full(N_PING - 1, 8.23)]) + 100.0  # 8.23 m a ping: 4 kn, 4 s
    ax = drawn(d)
    top = next(a for a in ax.child_axes if a.get_xlabel() == "along-track distance (m)")
    lo, hi = ax.get_xlim()
    # linear in the ping number, with ping 0 at d[0]: the limits half a ping beyond the first and last
    assert top.get_xlim() == pytest.approx((d[0] + lo * 8.23, d[0] + hi * 8.23), rel=1e-12)
