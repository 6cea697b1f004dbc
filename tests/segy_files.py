"""Multichannel SEG-Y files written with segyio alone, the way a sonar's exporter would, for the
import tests: every header value is an integer chosen here, with its SEG-Y rev 1 meaning."""

from __future__ import annotations

import numpy as np
import segyio

T, B = segyio.TraceField, segyio.BinField
N_PINGS, N_CH, N_S = 3, 8, 1000
ENSEMBLES = (101, 102, 103)
PITCH_M = 0.055125  # the SBP29's element pitch (3.528 m / 64)
DELAY = (127, 128, 131)  # DelayRecordingTime, with the time scalar -10: 12.7, 12.8, 13.1 ms
ROLL_UDEG = (1_250_000, -2_500_000, 0)  # roll, micro-degrees
HEADING_UDEG = (90_000_000, 91_500_000, 359_999_999)
HEAVE_MM = (12, -7, 0)  # SourceSurfaceElevation, with ElevationScalar -1000: millimetres
DRAFT_MM = (5000, 5012, 4990)  # SourceDepth, with ElevationScalar -1000: millimetres
SPEED = (1500, 1501, 1499)  # WeatheringVelocity, m/s
LAT_MAS = (123_480_000, 123_480_360, 123_480_720)  # SourceY, 1/1000 arc-second (scalar -1000): 34.3 degrees
LON_MAS = (-431_280_000, -431_280_072, -431_280_144)  # SourceX: -119.8 degrees
TIME = ((2024, 60, 23, 59, 58), (2024, 60, 23, 59, 59), (2024, 61, 0, 0, 3))  # 29 Feb, 29 Feb, 1 Mar
DEAD = (1, 5)  # ping 1's channel 6 (0-based 5) is a dead trace


def element_y_m(n=N_CH):
    return (np.arange(n) - (n - 1) / 2) * PITCH_M


def element_z_mm(n=N_CH):
    return np.arange(n) * 10 - 30  # ReceiverGroupElevation, with ElevationScalar -1000: millimetres


def write_vendor_segy(path, *, text=None, shuffle=True, sweep=(0, 0, 0), trace_interval=25, binary_interval=25,
                      counts=None, extra=None):
    """A multichannel SEG-Y file written with segyio alone: ``N_PINGS`` ensembles of ``N_CH`` traces.

    The traces are stored ping-interleaved and channel-reversed (``shuffle``), as an exporter
    might; ``counts`` gives the traces of each ensemble; ``extra(i, j)`` adds header fields.
    Returns the ``(ping, channel, sample)`` float32 samples written.
    """
    counts = counts or [N_CH] * N_PINGS
    rng = np.random.default_rng(7)
    samples = rng.standard_normal((N_PINGS, N_CH, N_S)).astype(np.float32)
    order = [(i, j) for i in range(N_PINGS) for j in range(counts[i])]
    if shuffle:
        order = sorted(order, key=lambda ij: (-ij[1], ij[0]))
    spec = segyio.spec()
    spec.format, spec.samples, spec.tracecount, spec.endian = 5, np.arange(N_S) * 0.025, len(order), "big"
    y_units = np.rint(element_y_m() * 1e7).astype(int)  # the default mapping: offset in 0.1 micrometre
    with segyio.create(str(path), spec) as f:
        f.bin.update({B.Interval: binary_interval, B.Samples: N_S, B.Format: 5, B.SweepFrequencyStart: sweep[0],
                      B.SweepFrequencyEnd: sweep[1], B.SweepLength: sweep[2]})
        if text is not None:
            f.text[0] = segyio.tools.create_text_header({k + 1: line for k, line in enumerate(text)})
        for t, (i, j) in enumerate(order):
            h = {T.FieldRecord: ENSEMBLES[i], T.TraceNumber: j + 1, T.TRACE_SAMPLE_INTERVAL: trace_interval,
                 T.TRACE_SAMPLE_COUNT: N_S, T.DelayRecordingTime: DELAY[i], T.ScalarTraceHeader: -10,
                 T.offset: int(y_units[j]), T.ReceiverGroupElevation: int(element_z_mm()[j]),
                 T.SourceSurfaceElevation: HEAVE_MM[i], T.SourceDepth: DRAFT_MM[i], T.ElevationScalar: -1000,
                 T.WeatheringVelocity: SPEED[i], T.UnassignedInt1: ROLL_UDEG[i], T.UnassignedInt2: HEADING_UDEG[i],
                 T.SourceX: LON_MAS[i], T.SourceY: LAT_MAS[i], T.SourceGroupScalar: -1000, T.CoordinateUnits: 2,
                 T.TraceIdentificationCode: 2 if (i, j) == DEAD else 1, T.TimeBaseCode: 4,
                 **dict(zip((T.YearDataRecorded, T.DayOfYear, T.HourOfDay, T.MinuteOfHour, T.SecondOfMinute),
                            TIME[i]))}
            h.update(extra(i, j) if extra else {})
            f.header[t] = h
            f.trace[t] = samples[i, j]
    return samples


TEXT = ["VENDOR X MULTICHANNEL EXPORT", "pulse_f0=2000.0 pulse_f1=9000.0", "pulse_duration=0.02",
        "source_x=0.0 source_y=0.25 source_z=-0.125", "tx_delay=0.001"]
