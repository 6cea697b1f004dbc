"""Packed windows of range cells (clbeam.model.grid.window_cells) against a boolean mask of the same cells."""

import numpy as np

from clbeam.model.grid import window_cells


def test_window_cells_are_the_masks_cells_in_row_order_and_pack_with_the_padding():
    rng = np.random.default_rng(0)
    n_rows, n_range, pad = 12, 30, 3
    first = rng.integers(0, n_range, n_rows)
    lengths = np.minimum(rng.integers(0, 12, n_rows), n_range - first)
    lengths[2] = 0
    mask = (np.arange(n_range)[None, :] >= first[:, None]) & (np.arange(n_range)[None, :] < (first + lengths)[:, None])
    grid_index, packed_index = window_cells(first, lengths, n_range, pad=pad)
    np.testing.assert_array_equal(grid_index, np.flatnonzero(mask))
    # packed: row i's window starts after the earlier rows' cells and 2 pad per earlier row, plus its own pad
    rows = np.repeat(np.arange(n_rows), lengths)
    starts = np.r_[0, np.cumsum(lengths + 2 * pad)[:-1]] + pad
    np.testing.assert_array_equal(packed_index, starts[rows] + grid_index % n_range - first[rows])
    assert np.array_equal(window_cells(first, lengths, n_range)[1], np.arange(lengths.sum()))
