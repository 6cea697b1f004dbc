"""Association of detections across pings into objects (Holland et al. 2024, Figs. 9-10).

A buried pipeline gives a detection at nearly the same place in ping after
ping; a false alarm does not repeat.  :func:`associate` links detections of
nearby pings that lie close across the track and in depth, and keeps the
connected groups that span enough pings (:class:`AssociationOptions`);
:func:`describe_objects` summarises each group.
"""

from __future__ import annotations

import numpy as np

from clbeam.survey.options import AssociationOptions


def associate(ping, position_m, starboard, z_m, options: AssociationOptions | None = None) -> np.ndarray:
    """Associate detections across pings into objects (see :class:`AssociationOptions`).

    Parameters
    ----------
    ping : array_like of int
        ``(n,)`` survey ping of each detection.
    position_m : array_like
        ``(n, 2)`` horizontal positions (m): easting and northing, or
        along- and across-track distance.
    starboard : array_like
        ``(n, 2)`` unit vectors to starboard of each detection's ping in the
        same frame (``(cos h, -sin h)`` in easting/northing for heading
        ``h``; ``(0, 1)`` in along/across).
    z_m : array_like
        ``(n,)`` depths (m).
    options : AssociationOptions, optional

    Returns
    -------
    numpy.ndarray
        ``(n,)`` int: object number (0, 1, … ordered by first ping, then
        mean position) or -1 for a detection left alone.
    """
    import scipy.sparse
    from scipy.sparse.csgraph import connected_components

    o = options or AssociationOptions()
    p = np.asarray(ping, dtype=np.int64)
    pos = np.asarray(position_m, dtype=np.float64).reshape(-1, 2)
    sb = np.asarray(starboard, dtype=np.float64).reshape(-1, 2)
    z = np.asarray(z_m, dtype=np.float64)
    n = p.size
    labels = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return labels
    r, c = _links(p, pos, sb, z, o)
    graph = scipy.sparse.coo_matrix((np.ones(r.size), (r, c)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    keep = []
    for lab in np.unique(comp):
        m = comp == lab
        if np.unique(p[m]).size >= o.min_pings:
            keep.append((int(p[m].min()), _mean(pos[m, 0]), _mean(pos[m, 1]), lab))
    keep.sort(key=lambda t: (t[0], np.nan_to_num(t[1]), np.nan_to_num(t[2])))
    for num, (*_, lab) in enumerate(keep):
        labels[comp == lab] = num
    return labels


def _mean(v: np.ndarray) -> float:
    """Mean of the finite values; NaN (without a warning) when there is none (an unknown along-track distance)."""
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else float("nan")


def _links(p, pos, sb, z, o: AssociationOptions) -> tuple:
    """Index pairs ``(later, earlier)`` of linked detections: each ping against the pings up to the gap before it."""
    order = np.argsort(p, kind="stable")
    ps = p[order]
    pings, starts = np.unique(ps, return_index=True)
    ends = np.r_[starts[1:], p.size]
    rows, cols = [], []
    reach = int(o.max_gap_pings) + 1
    for k, pk in enumerate(pings):
        b = order[starts[k]:ends[k]]
        lo = np.searchsorted(pings, pk - reach)
        if lo == k:
            continue
        a = order[starts[lo]:starts[k]]
        d = pos[b][:, None, :] - pos[a][None, :, :]
        s = sb[b][:, None, :]
        # a frame axis the starboard vector does not use (e.g. an unknown along-track distance) adds nothing
        across = np.abs(np.where(s == 0, 0.0, d * s).sum(axis=-1))
        dz = np.abs(z[b][:, None] - z[a][None, :])
        ok = np.isfinite(across) & (across <= o.link_distance_m) & (dz <= o.depth_tolerance_m)
        ib, ia = np.nonzero(ok)
        rows.append(b[ib])
        cols.append(a[ia])
    if rows:
        return np.concatenate(rows), np.concatenate(cols)
    return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)


def describe_objects(labels, ping, position_m, cf, y_m, z_m) -> list:
    """Summaries of the objects found by :func:`associate`.

    Parameters
    ----------
    labels : array_like of int
        ``(n,)`` object of each detection (-1: none).
    ping : array_like of int
        ``(n,)`` survey pings.
    position_m : array_like
        ``(n, 2)`` positions in the association frame (m).
    cf : array_like
        ``(n,)`` coherence factors.
    y_m, z_m : array_like
        ``(n,)`` cross-track offsets and depths (m).

    Returns
    -------
    list of dict
        One per object, in object order: ``object``, ``n_pings``,
        ``n_detections``, ``first_ping``, ``last_ping``, ``length_m`` (m, the
        polyline through the per-ping mean positions, in ping order),
        ``mean_cf``, ``max_cf``, ``mean_y_m``, ``mean_z_m`` (m) and the
        polyline ``path`` (``(k, 2)``, m).
    """
    labels = np.asarray(labels)
    p, pos = np.asarray(ping), np.asarray(position_m, dtype=np.float64).reshape(-1, 2)
    cf, y, z = (np.asarray(a, dtype=np.float64) for a in (cf, y_m, z_m))
    out = []
    for num in range(int(labels.max()) + 1 if labels.size else 0):
        m = np.flatnonzero(labels == num)
        pings = np.unique(p[m])
        path = np.array([pos[m[p[m] == q]].mean(axis=0) for q in pings])
        seg = np.hypot(*np.diff(path, axis=0).T) if len(path) > 1 else np.zeros(0)
        out.append({"object": num, "n_pings": int(pings.size), "n_detections": int(m.size),
                    "first_ping": int(pings[0]), "last_ping": int(pings[-1]),
                    "length_m": float(seg.sum()), "mean_cf": float(cf[m].mean()), "max_cf": float(cf[m].max()),
                    "mean_y_m": float(y[m].mean()), "mean_z_m": float(z[m].mean()), "path": path})
    return out
