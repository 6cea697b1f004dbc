"""The float32 kernels' Lanczos weights: polynomials against the closed-form kernel, and the header's
coefficients against a fresh fit."""

from __future__ import annotations

import re
from importlib import resources

import numpy as np
import pytest

from clbeam.imaging.engine.lanczos import lanczos, lanczos_polynomials, polynomial_weights


def header_coefficients(lobes: int) -> tuple[np.ndarray, np.ndarray]:
    """The LANCZOS_EVEN and LANCZOS_ODD tables of kernels/interp.h for ``lobes``."""
    text = resources.files("kernels").joinpath("interp.h").read_text()
    block = re.search(rf"#if LANCZOS_A == {lobes}\n__constant(.*?)#endif", text, re.S).group(1)
    tables = []
    for name in ("LANCZOS_EVEN", "LANCZOS_ODD"):
        body = re.search(rf"{name}\[{lobes}\]\[5\] = \{{(.*?)\}};", block, re.S).group(1)
        tables.append(np.array([float(v.rstrip("f")) for v in re.findall(r"[-+0-9.e]+f", body)]).reshape(lobes, 5))
    return tables[0], tables[1]


@pytest.mark.parametrize("lobes", [4, 8])
def test_closed_form_kernel_is_the_textbook_one(lobes):
    """L is the product of normalised sincs, sinc(x) sinc(x / A), 1 at 0, 0 at the other integers and
    beyond A."""
    x = np.linspace(-lobes + 0.01, lobes - 0.01, 997)
    np.testing.assert_allclose(lanczos(x, lobes), np.sinc(x) * np.sinc(x / lobes), atol=1e-15)
    np.testing.assert_allclose(lanczos(np.arange(-lobes + 1, lobes), lobes), np.eye(1, 2 * lobes - 1, lobes - 1)[0],
                               atol=1e-15)
    assert lanczos(np.array([lobes, lobes + 0.5]), lobes).tolist() == [0.0, 0.0]


@pytest.mark.parametrize("lobes", [4, 8])
def test_polynomial_weights_are_the_kernel_within_float32_rounding(lobes):
    """At 20 001 fractions, every tap's weight evaluated in float32 from the header's coefficients is within
    2e-7 of L(t + A - 1 - m) in float64 (float32's spacing near 1 is 1.2e-7); the float64 fit alone is
    within 5e-8."""
    t = np.linspace(0.0, 1.0, 20001)[:-1]
    exact = lanczos(t[:, None] + lobes - 1 - np.arange(2 * lobes)[None, :], lobes)
    even, odd = header_coefficients(lobes)
    assert np.max(np.abs(polynomial_weights(t, even, odd, np.float32) - exact)) < 2e-7
    fit_even, fit_odd = lanczos_polynomials(lobes)
    assert np.max(np.abs(polynomial_weights(t, fit_even, fit_odd, np.float64) - exact)) < 5e-8


@pytest.mark.parametrize("lobes", [4, 8])
def test_header_holds_the_fitted_coefficients(lobes):
    """kernels/interp.h holds lanczos_polynomials' coefficients, rounded to float32."""
    even, odd = header_coefficients(lobes)
    fit_even, fit_odd = lanczos_polynomials(lobes)
    np.testing.assert_allclose(even, fit_even.astype(np.float32), rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(odd, fit_odd.astype(np.float32), rtol=1e-8, atol=1e-12)
