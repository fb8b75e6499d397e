# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""One triangle of a symmetric sparse matrix, in compiled passes: its mirror as CSR arrays, the DOF
structure of CalculiX's lower triangle, and the count of entries that no positive semi-definite
matrix has.  Index arrays of CSR matrices are int32 or int64 (scipy's choice), triplets int64."""

import numpy as np
from libc.stdint cimport int32_t, int64_t

ctypedef fused index_t:
    int32_t
    int64_t


def mirror_counts(const int64_t[:] i, const int64_t[:] j, int64_t n):
    """(n + 1,) int64: 0, then the entries of each row of the symmetric (n, n) matrix whose one
    triangle are the pairs (i, j): each pair in row i and, off the diagonal, in row j.  ValueError
    when an index is outside 0..n-1."""
    counts = np.zeros(n + 1, dtype=np.int64)
    cdef int64_t[::1] c = counts
    cdef Py_ssize_t k, outside = -1
    with nogil:
        for k in range(i.shape[0]):
            if not (0 <= i[k] < n and 0 <= j[k] < n):
                outside = k
                break
            c[i[k] + 1] += 1
            if i[k] != j[k]:
                c[j[k] + 1] += 1
    if outside >= 0:
        raise ValueError(f"pair {outside} ({i[outside]}, {j[outside]}) is outside a {n} x {n} matrix")
    return counts


def mirror_fill(const int64_t[:] i, const int64_t[:] j, const double[:] v, const int64_t[::1] indptr,
                index_t[::1] indices, double[::1] data):
    """Each pair (i, j, v) into row i of the CSR arrays ``indices``, ``data`` (row starts ``indptr``:
    the cumulative sum of mirror_counts) and, off the diagonal, its mirror (j, i, v) into row j; in
    the order given within each row."""
    cdef int64_t[::1] fill = np.array(indptr[:indptr.shape[0] - 1])
    cdef Py_ssize_t k
    cdef int64_t a, b
    with nogil:
        for k in range(i.shape[0]):
            a, b = i[k], j[k]
            indices[fill[a]] = <index_t>b
            data[fill[a]] = v[k]
            fill[a] += 1
            if a != b:
                indices[fill[b]] = <index_t>a
                data[fill[b]] = v[k]
                fill[b] += 1


def indefinite_entries(const index_t[:] indptr, const index_t[:] indices, const double[:] data,
                       const double[:] diagonal, double rtol):
    """Number of stored entries of a CSR matrix with A_ij^2 > A_ii A_jj (1 + rtol): a symmetric
    positive semi-definite matrix has none (every 2 x 2 principal minor is >= 0)."""
    cdef Py_ssize_t r, k, bad = 0
    with nogil:
        for r in range(indptr.shape[0] - 1):
            for k in range(indptr[r], indptr[r + 1]):
                if data[k] * data[k] > diagonal[r] * diagonal[indices[k]] * (1.0 + rtol):
                    bad += 1
    return bad


def lower_dofs(const int64_t[:] indptr, const int64_t[:] indices):
    """DOF (columns, rows), int64, of the strict lower triangle of a node graph with 3 DOF per node
    (CalculiX's mastruct.f): given the graph's upper triangle in CSR (neighbours b >= a of each node a,
    sorted), column 3 a + ca holds the rows 3 b + cb > 3 a + ca, column by column, rows increasing."""
    cdef Py_ssize_t a, k, pos = 0, total = 0
    cdef int64_t ca, cb, col, row
    for a in range(indptr.shape[0] - 1):
        if indptr[a + 1] == indptr[a] or indices[indptr[a]] != a:
            raise ValueError(f"node {a} is not the first neighbour of itself: not a sorted upper triangle")
        total += 3 * 3 * (indptr[a + 1] - indptr[a]) - 6         # minus the diagonal block's upper part
    cols_array, rows_array = np.empty(total, np.int64), np.empty(total, np.int64)
    cdef int64_t[::1] cols = cols_array, rows = rows_array
    with nogil:
        for a in range(indptr.shape[0] - 1):
            for ca in range(3):
                col = 3 * a + ca
                for k in range(indptr[a], indptr[a + 1]):
                    for cb in range(3):
                        row = 3 * indices[k] + cb
                        if row > col:
                            cols[pos] = col
                            rows[pos] = row
                            pos += 1
    return cols_array, rows_array
