"""FCLib problem files (HDF5) through h5py, so that the compiled extension links no libhdf5.

A file holds a group ``/fclib_global`` (matrices ``M``, ``H`` and optionally ``G``; vectors
``f``, ``w``, ``mu`` and ``b``) or ``/fclib_local`` (``W``; ``q``, ``mu``). A matrix group
holds ``m, n, nz, nzmax`` and ``p, i, x``: ``nz = -1`` is compressed column (``p`` column
pointers), ``nz = -2`` compressed row (``p`` row pointers), ``nz >= 0`` that many triplets,
with row indices in ``i`` and column indices in ``p`` as Siconos writes them.
"""

from __future__ import annotations

import os
from typing import Union

import numpy as np
import scipy.sparse as sp

from ._cadmm import GlobalProblem, LocalProblem
from .errors import IoError

Problem = Union[GlobalProblem, LocalProblem]


def _h5py():
    try:
        import h5py
    except ImportError as e:  # an optional dependency: say how to get it
        raise ImportError("FCLib files need h5py: pip install 'cadmm[fclib]'") from e
    return h5py


def _scalar(group, name: str) -> int:
    return int(np.asarray(group[name][()]).ravel()[0])


def _matrix(group, name: str, path) -> sp.csc_array:
    if name not in group:
        raise IoError(f"{path}: no matrix {name}")
    g = group[name]
    m, n, nz = _scalar(g, "m"), _scalar(g, "n"), _scalar(g, "nz")
    p, i, x = (np.asarray(g[k][()]).ravel() for k in ("p", "i", "x"))
    if nz == -1:
        end = int(p[n])
        return sp.csc_array((x[:end], i[:end], p[: n + 1]), shape=(m, n))
    if nz == -2:
        end = int(p[m])
        return sp.csr_array((x[:end], i[:end], p[: m + 1]), shape=(m, n)).tocsc()
    if nz >= 0:
        rows, cols = i[:nz], p[:nz]
        if nz and (rows.max() >= m or cols.max() >= n) and rows.max() < n and cols.max() < m:
            rows, cols = cols, rows  # the other convention of the triplet arrays
        return sp.coo_array((x[:nz], (rows, cols)), shape=(m, n)).tocsc()
    raise IoError(f"{path}: matrix {name}: unknown encoding nz = {nz}")


def _vector(group, name: str, path) -> np.ndarray:
    if name not in group:
        raise IoError(f"{path}: no vector {name}")
    return np.asarray(group[name][()], dtype=np.float64).ravel()


def read_fclib(path: Union[str, os.PathLike]) -> Problem:
    """Reads the problem of an FCLib file: a :class:`GlobalProblem` or a :class:`LocalProblem`.

    Raises :class:`cadmm.IoError` when the file is not an FCLib problem, and the problem's
    own exceptions when its data are inconsistent.
    """
    h5py = _h5py()
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise IoError(f"{path}: {e}") from e
    with f:
        if "fclib_global" in f:
            g = f["fclib_global"]
            v = g["vectors"]
            joints = {}
            if "G" in g:
                joints = {"G": _matrix(g, "G", path), "b": _vector(v, "b", path)}
            return GlobalProblem(
                _matrix(g, "M", path),
                _matrix(g, "H", path),
                _vector(v, "f", path),
                _vector(v, "w", path),
                _vector(v, "mu", path),
                **joints,
            )
        if "fclib_local" in f:
            g = f["fclib_local"]
            v = g["vectors"]
            return LocalProblem(_matrix(g, "W", path), _vector(v, "q", path), _vector(v, "mu", path))
    raise IoError(f"{path}: neither an fclib_global nor an fclib_local group")


def _write_matrix(parent, name: str, a) -> None:
    a = sp.csc_array(a)
    g = parent.create_group(name)
    for key, value in (("m", a.shape[0]), ("n", a.shape[1]), ("nz", -1), ("nzmax", a.nnz)):
        g.create_dataset(key, data=np.array([value], dtype=np.int32))
    g.create_dataset("p", data=a.indptr.astype(np.int32))
    g.create_dataset("i", data=a.indices.astype(np.int32))
    g.create_dataset("x", data=a.data.astype(np.float64))


def write_fclib(problem: Problem, path: Union[str, os.PathLike]) -> None:
    """Writes ``problem`` as an FCLib file (matrices in compressed-column form), replacing ``path``."""
    h5py = _h5py()
    with h5py.File(path, "w") as f:
        if isinstance(problem, GlobalProblem):
            g = f.create_group("fclib_global")
            matrices = {"M": problem.M, "H": problem.H}
            vectors = {"f": problem.f, "w": problem.w, "mu": problem.mu}
            if problem.n_joints:
                matrices["G"], vectors["b"] = problem.G, problem.b
        elif isinstance(problem, LocalProblem):
            g = f.create_group("fclib_local")
            matrices = {"W": problem.W}
            vectors = {"q": problem.q, "mu": problem.mu}
        else:
            raise TypeError("expected a cadmm.GlobalProblem or a cadmm.LocalProblem")
        g.create_dataset("spacedim", data=np.array([3], dtype=np.int32))
        for name, a in matrices.items():
            _write_matrix(g, name, a)
        v = g.create_group("vectors")
        for name, x in vectors.items():
            v.create_dataset(name, data=x)


__all__ = ["read_fclib", "write_fclib"]
