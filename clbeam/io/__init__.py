"""Everything that reads or writes files: the ping-file and image-file
formats (one schema, :mod:`clbeam.io.schema`), peak tables, figures, SEG-Y
and the survey store.  Imports only :mod:`clbeam.model`, constants and errors."""

from clbeam.lazy import lazy_exports

_EXPORTS = {
    "clbeam.io.images": ("ImageWriter", "open_images"),
    "clbeam.io.peaks": ("read_peaks_csv", "write_peaks_csv"),
    "clbeam.io.pingfile": ("PingDataset", "PingFile", "pings_from_dataset"),
    "clbeam.io.pingwrite": ("dataset_from_pings", "write_ping_file"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
