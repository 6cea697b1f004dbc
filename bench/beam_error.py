"""Intensity error of beam-sampled imaging against the beams' oversampling and
taps, measured and predicted by the error model (the figure of docs/beams.md).

    python bench/beam_error.py [-o docs/beam_error.png] [--scene line4]

One simulated ping of the bench's scene is imaged with Lanczos-8 on the
paper's angles (±80° every 0.1°) every 0.2 m over two range windows, one
starting at the seabed below the ship (230-350 m: the seabed from nadir out
to 49°) and one at the swath's edge (880-1000 m: 75-80°): every cell
directly, then from beams sampled ``K`` times the aperture's band limit and
interpolated with ``T`` taps.  Both use the same time interpolation, so
their difference is the angle interpolation's error alone; it is reported
as the bench reports errors (error energy over signal energy on the cells
within 40 dB of the maximum).  The lines are the model's prediction of the
same quantity (:func:`clbeam.imaging.engine.errormodel.beam_error` on the
scene's angular spectrum), the one ``--max-error-db`` chooses with.  The
model takes the band limit at nadir, where the sums vary fastest in angle
(the delays change with ``cos θ``); far from nadir the same beams sample
the sums more finely than the model assumes, so it is conservative there.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

OVERSAMPLING = (1.0, 1.25, 1.5, 2.0, 3.0)
TAPS = (4, 6, 8, 12, 16)
#: range windows (m): the seabed from nadir outwards, and the swath's edge
WINDOWS = ((230.0, 350.0), (880.0, 1000.0))


def measure(scene: str) -> tuple[dict, dict]:
    """Measured errors (dB) by ``(window, K, T)`` and predicted ones by ``(K, T)``."""
    from clbeam.evaluation.bench import intensity_error_db
    from clbeam.imaging.engine import get_engine
    from clbeam.imaging.engine.beams import BeamSampling
    from clbeam.imaging.engine.errormodel import INTENSITY_FACTOR, angular_spectrum, beam_error
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.model.grid import PolarGrid
    from clbeam.sim import load_scene, simulate

    ping = pings_from_dataset(simulate(load_scene(scene, pings=1)), scene).ping(0)
    engine = get_engine("opencl")
    measured, predicted = {}, {}
    for window in WINDOWS:
        grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=window[0], max_range_m=window[1],
                                 angles_deg=(-80.0, 80.0))
        inp = Imager(grid, ImagingOptions(use_svp=False), engine=engine).beamform_input(ping)
        direct = engine.beamform(inp, grid, interp="lanczos8", outputs=("intensity",)).intensity.astype(np.float64)
        for k in OVERSAMPLING:
            for t in TAPS:
                got = engine.beamform(inp, grid, interp="lanczos8", outputs=("intensity",), beams=BeamSampling(k, t))
                measured[window, k, t] = intensity_error_db(got.intensity.astype(np.float64), direct)
    across = np.linalg.norm(ping.element_pos_m[:, 1:] - ping.source_pos_m[1:], axis=1)
    limit = inp.top_frequency_hz * float(np.max(across)) / inp.sound_speed_m_s
    for k in OVERSAMPLING:
        nu, power = angular_spectrum(across, inp.band_hz, inp.sound_speed_m_s, 1.0 / (2.0 * limit * k))
        for t in TAPS:
            predicted[k, t] = 10 * math.log10(max(INTENSITY_FACTOR * beam_error(BeamSampling(k, t), nu, power), 1e-30))
            print(f"K {k:<5g} T {t:<3d} predicted {predicted[k, t]:6.1f} dB, measured "
                  + ", ".join(f"{w[0]:g}-{w[1]:g} m {measured[w, k, t]:6.1f} dB" for w in WINDOWS), flush=True)
    return measured, predicted


def plot(measured: dict, predicted: dict, path) -> None:
    """Error against oversampling per window, one colour per tap count: points measured, lines predicted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(WINDOWS), figsize=(10, 4.2), sharey=True)
    for ax, window in zip(axes, WINDOWS):
        for i, t in enumerate(TAPS):
            colour = f"C{i}"
            ax.plot(OVERSAMPLING, [predicted[k, t] for k in OVERSAMPLING], "-", color=colour, alpha=0.7)
            ax.plot(OVERSAMPLING, [measured[window, k, t] for k in OVERSAMPLING], "o", color=colour,
                    label=f"{t} taps")
        ax.axhline(-40, color="grey", lw=0.8, ls="--")
        ax.set_xlabel("beam oversampling K (beams every 1/(2 B K) rad)")
        ax.set_title(f"{window[0]:g}-{window[1]:g} m (points measured, lines predicted)", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("intensity error of the angle interpolation (dB)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="docs/beam_error.png", help="figure to write (PNG)")
    parser.add_argument("--scene", default="line4", help="scene to simulate one ping of (default line4)")
    args = parser.parse_args()
    measured, predicted = measure(args.scene)
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    plot(measured, predicted, args.output)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
