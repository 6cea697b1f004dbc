"""Everything that reads or writes files: the ping-file and image-file
formats (one schema, :mod:`clbeam.io.schema`), peak tables, figures, SEG-Y
and the survey store.  Imports only :mod:`clbeam.model`, constants and errors."""

from clbeam.io.images import ImageWriter, open_images
from clbeam.io.peaks import read_peaks_csv, write_peaks_csv
from clbeam.io.pingfile import PingDataset, PingFile, pings_from_dataset
from clbeam.io.pingwrite import dataset_from_pings, write_ping_file

__all__ = ["ImageWriter", "PingDataset", "PingFile", "dataset_from_pings", "open_images", "pings_from_dataset",
           "read_peaks_csv", "write_peaks_csv", "write_ping_file"]
