"""Ping stacking: linear-intensity mean, patch bookkeeping."""

import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.seabed.avo import stack as sk

INC = np.array([5.0, 30.0, 60.0])


def test_linear_mean_hand_value():
    # -10 dB and -20 dB: 10 log10((0.1 + 0.01)/2) = 10 log10(0.055) = -12.5964 dB.
    assert sk.stack_linear_db(np.array([[-10.0], [-20.0]]))[0] == pytest.approx(-12.5964, abs=1e-4)
    assert np.isnan(sk.stack_linear_db(np.array([[np.nan], [np.nan]]))[0])


def test_linear_stacking_is_unbiased_under_speckle_while_db_mean_is_not():
    # Fully developed speckle: intensity ~ exponential with mean mu.  The
    # linear mean of n samples has relative sd 1/sqrt(n): n = 6000 ->
    # 4.343/sqrt(6000) = 0.056 dB; 4 sd = 0.23 dB.  The mean of the dB
    # values is low by 10 log10(e) * Euler-gamma = 2.507 dB (closed form),
    # its sd 5.57 dB/sqrt(n) = 0.072 dB; 4 sd = 0.29 dB.
    rng = np.random.default_rng(7)
    mu_db = np.array([-15.0, -25.0, -35.0])
    inten = rng.exponential(10 ** (mu_db / 10), size=(6000, 3))
    s_db = 10 * np.log10(inten)
    assert sk.stack_linear_db(s_db) == pytest.approx(mu_db, abs=0.23)
    bias = 10 * math.log10(math.e) * np.euler_gamma
    assert s_db.mean(axis=0) == pytest.approx(mu_db - bias, abs=0.29)


def test_patches_cover_consecutive_pings_with_partial_tail():
    s = np.zeros((65, 3))
    pos = np.arange(65) * 2.0
    patches = sk.stack_pings(INC, s, side="port", pings_per_patch=30, along_track_m=pos, first_ping=100)
    assert [(p.ping_start, p.ping_stop) for p in patches] == [(100, 130), (130, 160), (160, 165)]
    # Mean position of pings 0..29 at 2 m spacing: 29 m; of 60..64: 124 m.
    assert [p.along_track_m for p in patches] == [29.0, 89.0, 124.0]
    full = sk.stack_pings(INC, s, side="port", pings_per_patch=30, keep_partial=False)
    assert len(full) == 2 and math.isnan(full[0].along_track_m)


def test_ping_count_and_nan_bins():
    s = np.full((4, 3), -20.0)
    s[:, 2] = np.nan
    s[0, 0] = np.nan
    (p,) = sk.stack_pings(INC, s, side="starboard", pings_per_patch=4)
    assert list(p.ping_count) == [3, 4, 0]
    assert p.strength_db[0] == pytest.approx(-20.0, abs=1e-12)
    assert np.isnan(p.strength_db[2])


def test_stack_sides_interleaves_port_then_starboard():
    port, stbd = np.full((60, 3), -10.0), np.full((60, 3), -30.0)
    patches = sk.stack_sides(INC, port, stbd, pings_per_patch=30)
    assert [p.side for p in patches] == ["port", "starboard", "port", "starboard"]
    assert patches[1].strength_db[0] == pytest.approx(-30.0)


def test_bad_inputs_raise():
    with pytest.raises(OptionError, match="side"):
        sk.stack_pings(INC, np.zeros((2, 3)), side="aft")
    with pytest.raises(OptionError, match="strength_db"):
        sk.stack_pings(INC, np.zeros((2, 4)), side="port")
    with pytest.raises(OptionError, match="pings_per_patch"):
        sk.stack_pings(INC, np.zeros((2, 3)), side="port", pings_per_patch=0)
