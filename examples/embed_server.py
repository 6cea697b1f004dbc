"""Embedding clbeam in a processing server.

One Imager is built at start-up (device, grid, mode, outputs): it compiles the
kernel once and keeps its device buffers.  Worker threads then image pings as
they arrive; the engine serialises its device calls with a lock while the
host work (pulse compression, smoothing, peaks) runs in parallel.  Bad pings
raise clbeam.errors.ClbeamError with a one-line reason and the server goes on.

    python examples/embed_server.py PINGS.nc [--threads 4]
"""

from __future__ import annotations

import argparse
import logging
import queue
import sys
import threading

from clbeam.errors import ClbeamError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile
from clbeam.model.grid import PolarGrid

log = logging.getLogger("embed_server")


def serve(pings, imager: Imager, n_threads: int = 4) -> dict:
    """Image every ping of an iterable with ``n_threads`` workers; return
    ``{ping index: number of coherence peaks}`` (or the error text)."""
    jobs: queue.Queue = queue.Queue(maxsize=2 * n_threads)  # bounded: memory stays flat
    results: dict = {}
    lock = threading.Lock()

    def worker():
        while True:
            ping = jobs.get()
            if ping is None:
                return
            try:
                img = imager.image(ping)
                out = len(img.peaks)
            except ClbeamError as exc:  # a bad ping: report it, keep serving
                log.warning("ping %d rejected: %s", ping.index, exc)
                out = f"error: {exc}"
            with lock:
                results[ping.index] = out

    threads = [threading.Thread(target=worker, daemon=True) for _ in range(n_threads)]
    for t in threads:
        t.start()
    for ping in pings:
        jobs.put(ping)
    for _ in threads:
        jobs.put(None)
    for t in threads:
        t.join()
    return results


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("pings")
    p.add_argument("--threads", type=int, default=4)
    p.add_argument("--max-range", type=float, default=300.0)
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.2, max_range_m=args.max_range, angles_deg=(-80, 80))
    imager = Imager(grid, ImagingOptions(interp="linear"))
    log.info("device: %s", getattr(imager.engine, "label", imager.engine.name))
    try:
        with PingFile(args.pings) as f:
            results = serve(f, imager, args.threads)
    except ClbeamError as exc:
        print(f"embed_server: {exc}", file=sys.stderr)
        return 2
    finally:
        release = getattr(imager.engine, "release", None)
        if release:
            release()  # free device memory; the compiled kernels stay for the next job
    for k in sorted(results):
        log.info("ping %d: %s coherence peaks", k, results[k])
    return 0


if __name__ == "__main__":
    sys.exit(main())
