"""Measuring clbeam: run time against error of every mode
(:mod:`clbeam.evaluation.bench`), the numba baseline, detections scored
against the simulator's truth (:mod:`clbeam.evaluation.scoring`) and the demo."""
