"""The grid search of nearest neighbours compares each query's candidates all at once and keeps
the neighbour a comparison one by one keeps: the first at the least distance, in cell order."""

import numpy as np
import pytest

from ppo_cv import model_selection
from ppo_cv.model_selection import nearest_neighbours


def _one_by_one_pass(p, queries, low, side, best, best_d2):
    """The grid pass with each cell's points compared one slot at a time, the reference."""
    cell = np.floor((p - low) / side).astype(np.int64)
    width = int(cell[:, 0].max()) + 3
    key = (cell[:, 1] + 1) * width + cell[:, 0] + 1
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    crowded = np.zeros(queries.size, dtype=bool)
    for shift in (np.arange(9) // 3 - 1) * width + np.arange(9) % 3 - 1:
        target = key[queries] + shift
        start = np.searchsorted(sorted_key, target, "left")
        count = np.searchsorted(sorted_key, target, "right") - start
        crowded |= count > model_selection._MAX_SLOTS
        count = np.minimum(count, model_selection._MAX_SLOTS)
        for slot in range(int(count.max(initial=0))):
            has = np.flatnonzero(count > slot)
            i, j = queries[has], order[start[has] + slot]
            d2 = np.sum((p[j] - p[i]) ** 2, axis=1)
            better = (d2 < best_d2[i]) & (j != i)
            best[i[better]], best_d2[i[better]] = j[better], d2[better]
    offset = (p[queries] - low) / side % 1.0
    margin = side * (1.0 + np.minimum(offset, 1.0 - offset).min(axis=1))
    return queries[crowded | (best_d2[queries] > margin**2)]


def _point_sets():
    rng = np.random.default_rng(3)
    n = 1500
    return {
        "uniform": rng.uniform(0, 640, (n, 2)),
        "lattice, ties and coincident points": np.round(rng.uniform(0, 25, (n, 2))),
        "a dense cluster in sparse points": np.concatenate(
            [rng.normal(0, 0.01, (n // 2, 2)), rng.uniform(0, 100, (n // 2, 2))]
        ),
        "groups of four coincident points": np.repeat(rng.uniform(0, 50, (n // 4, 2)), 4, axis=0),
        "a line": np.column_stack([np.arange(n, dtype=float), np.zeros(n)]),
    }


@pytest.mark.parametrize("chunk, table", [(1024, 16), (97, 16), (1024, 0)])
@pytest.mark.parametrize("name", list(_point_sets()))
def test_each_query_keeps_the_neighbour_of_the_one_by_one_comparison(
    monkeypatch, name, chunk, table
):
    points = _point_sets()[name]
    monkeypatch.setattr(model_selection, "_QUERY_CHUNK", chunk)
    monkeypatch.setattr(model_selection, "_CELL_TABLE_PER_POINT", table)
    found = nearest_neighbours(points)
    monkeypatch.setattr(model_selection, "_grid_pass", _one_by_one_pass)
    np.testing.assert_array_equal(found, nearest_neighbours(points))
    d2 = np.sum((points[:, None] - points[None]) ** 2, axis=2)
    np.fill_diagonal(d2, np.inf)
    np.testing.assert_array_equal(d2[np.arange(len(points)), found], d2.min(axis=1))
