"""OpenCL C sources of the clbeam kernels (shipped as package data)."""
