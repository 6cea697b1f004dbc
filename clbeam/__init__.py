"""clbeam: cross-track imaging of multibeam sub-bottom sonar element data.

The imaging chain of Holland et al. (2024): pulse compression and analytic
signal, roll correction, spherical-wave delay-and-sum on a polar grid with
intensity and coherence factor (OpenCL kernels, with a float64 NumPy
reference), Hann smoothing and coherence-peak picking.
"""

__version__ = "0.1.0"
