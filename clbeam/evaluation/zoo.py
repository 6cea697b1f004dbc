"""The scene zoo: five pings on which the default setting and the whole command are judged.

- ``bench``: the bench's simulated Line 4 ping (`clbeam bench`), errors on the window around its 920 m pipe;
- ``jittered``: 48 elements over 3.0 m with 2 cm of jitter, roll 3 degrees, the source 0.35 m across and
  0.4 m down, five point echoes at 300-1000 m, on and off nodes;
- ``jump``: 1500 m/s water over 1560 m/s below 80 m (the profile in the ping), five points whose echoes
  have exact refracted times (eigenrays);
- ``points``: the SBP29 array and five noise-free point echoes at 200-1000 m;
- ``clutter``: the simulator's clutter-only scene (boulders, dense seabed and sub-bottom scatterers, noise),
  errors on a window of seabed 400-520 m out.

Point echoes are the 80 ms 2-9 kHz LFM placed with exact fractional delays (phase ramps), built here
independently of the imaging code.  ``bench/zoo.py`` measures each setting's errors on them;
:func:`zoo_command_times` (``clbeam bench``) times ``clbeam image`` as a whole on each.
"""

from __future__ import annotations

import dataclasses

import numpy as np

#: sample rate (Hz) and sound speed (m/s) of the point scenes
FS, C = 40000.0, 1500.0
#: the point scenes' LFM band (Hz) and length (s)
BAND, PULSE_S = (2000.0, 9000.0), 0.08
#: the point scenes' echoes: (range m, angle degree, on a node) from the grid centre
POINTS_RA = ((300.0, -35.0, True), (480.0, 12.0, False), (620.0, 55.0, True), (800.0, -62.0, False),
             (1000.0, 70.0, True))


def _lfm():
    from clbeam.model.pulse import Pulse

    return Pulse(f0_hz=BAND[0], f1_hz=BAND[1], duration_s=PULSE_S)


def _delayed(replica: np.ndarray, delays_s: np.ndarray, n: int) -> np.ndarray:
    nfft = 1 << int(np.ceil(np.log2(n + replica.size)))
    f = np.fft.rfftfreq(nfft, 1 / FS)
    spec = np.fft.rfft(replica, nfft)[None, :] * np.exp(-2j * np.pi * f[None, :] * delays_s[:, None])
    return np.fft.irfft(spec, nfft, axis=-1)[:, :n]


def _point_ping(targets_yz, *, elements, roll_deg=0.0, source=(0.0, 0.0, 0.0), profile=None):
    """A raw ping of unit point scatterers at earth-frame ``(y, z)`` from the array reference (m)."""
    from clbeam.imaging.geometry import to_earth_frame
    from clbeam.imaging.raytrace import element_travel_times
    from clbeam.model.ping import Ping

    pulse = _lfm()
    replica = pulse.replica(FS)
    el = to_earth_frame(elements, roll_deg=roll_deg)
    src = to_earth_frame(np.asarray(source, dtype=float), roll_deg=roll_deg)
    n = int(1.5 * FS)
    out = np.zeros((len(elements), n))
    for y, z in targets_yz:
        if profile is None:
            r = np.array([0.0, y, z])
            tau = (np.linalg.norm(r - src) + np.linalg.norm(r - el, axis=1)) / C
        else:
            pt = np.array([[y, z]])
            tau = element_travel_times(profile, src[None, 1:], pt)[0, 0] + element_travel_times(profile, el[:, 1:], pt)[:, 0]
        out += _delayed(replica, tau, n) / (np.hypot(y, z) ** 2)
    return Ping(samples=out, kind="raw", sample_rate_hz=FS, t0_s=0.0,
                sound_speed_m_s=C if profile is None else float(profile.speed(0.0)), element_pos_m=elements,
                source_pos_m=np.asarray(source, dtype=float), channel_valid=np.ones(len(elements), dtype=bool),
                roll_deg=roll_deg, pulse=pulse, svp=profile)


def _targets(grid, centre):
    """Earth-frame ``(y, z)`` of :data:`POINTS_RA` about the grid ``centre``, on nodes or off them, and their
    polar positions."""
    dr, da = 0.2, 0.1
    yz, polar = [], []
    for r, a, node in POINTS_RA:
        r, a = (r, a) if node else (r + 0.37 * dr, a + 0.41 * da)
        th = np.deg2rad(a)
        yz.append((centre[0] + r * np.sin(th), centre[1] + r * np.cos(th)))
        polar.append((r, a, node))
    return yz, polar


def zoo(grid) -> dict:
    """Scene name -> (ping, where its errors are measured: the points as (range m, angle degree, on a node)
    or a window grid) for the output ``grid``."""
    from clbeam.evaluation.bench import accuracy_window
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.model.svp import SoundSpeedProfile
    from clbeam.sim import load_scene, simulate

    scenes = {"bench": (pings_from_dataset(simulate(load_scene("line4", pings=1)), "line4").ping(0), accuracy_window())}
    rng = np.random.default_rng(7)
    jit = np.zeros((48, 3))
    jit[:, 1] = (np.arange(48) - 23.5) * 3.0 / 48
    jit[:, 1:] += rng.normal(0.0, 0.02, (48, 2))
    source = (0.0, 0.35, 0.4)
    yz, polar = _targets(grid, grid.centre(source[1:]))
    scenes["jittered"] = (_point_ping(yz, elements=jit, roll_deg=3.0, source=source), polar)
    sbp = np.zeros((64, 3))
    sbp[:, 1] = (np.arange(64) - 31.5) * 3.528 / 64
    yz, polar = _targets(grid, grid.centre((0.0, 0.0)))
    jump = SoundSpeedProfile([0.0, 80.0, 80.0, 2000.0], [1500.0, 1500.0, 1560.0, 1560.0])
    scenes["jump"] = (_point_ping(yz, elements=sbp, profile=jump), polar)
    scenes["points"] = (_point_ping(yz, elements=sbp), polar)
    clutter = pings_from_dataset(simulate(load_scene("clutter", pings=1)), "clutter").ping(0)
    from clbeam.model.grid import PolarGrid

    scenes["clutter"] = (clutter, PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=400.0,
                                                    max_range_m=520.0, angles_deg=(40.0, 52.0)))
    return scenes


def zoo_command_times(work_dir, pings: tuple = (1, 5), progress=None) -> dict:
    """Scene name -> :func:`clbeam.evaluation.bench.time_image_command` of ``clbeam image --peaks`` on ping
    files of ``pings[0]`` and ``pings[1]`` copies of the scene's ping (s; ``s_per_ping`` the difference over
    the extra pings), in ``work_dir``; ``progress(text)`` is told each scene."""
    from pathlib import Path

    from clbeam.evaluation.bench import paper_grid, time_image_command
    from clbeam.io.pingwrite import dataset_from_pings

    out = {}
    for name, (ping, _) in zoo(paper_grid()).items():
        if progress is not None:
            progress(f"clbeam image on the zoo's '{name}' scene, {pings[0]} and {pings[1]} pings")
        copies = [dataclasses.replace(ping, index=k) for k in range(pings[1])]
        dataset = dataset_from_pings(copies, samples_dtype=np.float32)
        out[name] = time_image_command(dataset, Path(work_dir) / name, pings=pings)
    return out
