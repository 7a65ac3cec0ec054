"""Bad input raises the exception documented for its C result code."""

import numpy as np
import pytest
import scipy.sparse as sp

import cadmm

I3 = np.eye(3)
F = [-9.81, 0.0, 0.0]
Z = np.zeros(3)


def test_the_classes_derive_as_documented():
    for name in ("DimensionError", "InvalidCscError", "InvalidValueError", "NotPositiveDefiniteError",
                 "SingularError", "InvalidSettingError", "PatternChangedError"):
        cls = getattr(cadmm, name)
        assert issubclass(cls, cadmm.Error) and issubclass(cls, ValueError), name
    assert issubclass(cadmm.OutOfMemoryError, MemoryError)
    assert issubclass(cadmm.IoError, OSError)


@pytest.mark.parametrize(
    "args",
    [
        (I3, I3, [1.0, 2.0], Z, [0.5]),  # f too short
        (np.eye(4), I3, F, Z, [0.5]),  # M and H disagree on n
        (I3, I3, F, np.zeros(6), [0.5]),  # w too long
        (I3, I3, F, Z, [0.5, 0.5]),  # two friction coefficients, one contact
        (np.ones(3), I3, F, Z, [0.5]),  # M not 2-D
        (I3, I3, np.ones((3, 1)), Z, [0.5]),  # f not 1-D
    ],
)
def test_sizes(args):
    with pytest.raises(cadmm.DimensionError):
        cadmm.GlobalProblem(*args)


@pytest.mark.parametrize("mu, f", [([-0.1], F), ([np.nan], F), ([0.5], [np.inf, 0.0, 0.0])])
def test_values(mu, f):
    with pytest.raises(cadmm.InvalidValueError):
        cadmm.GlobalProblem(I3, I3, f, Z, mu)


def test_non_finite_matrix_entry():
    m = I3.copy()
    m[1, 1] = np.nan
    with pytest.raises(cadmm.Error):
        cadmm.GlobalProblem(m, I3, F, Z, [0.5])


def test_matrix_that_is_not_positive_definite():
    p = cadmm.GlobalProblem(-I3, I3, F, Z, [0.5])
    with pytest.raises(cadmm.NotPositiveDefiniteError):
        cadmm.Solver(p)


def test_malformed_csc():
    bad = sp.csc_matrix((np.ones(3), np.array([0, 1, 7]), np.array([0, 1, 2, 3])), shape=(3, 3), copy=False)
    with pytest.raises(cadmm.InvalidCscError):
        cadmm.GlobalProblem(bad, I3, F, Z, [0.5])


def test_settings():
    with pytest.raises(cadmm.InvalidSettingError):
        cadmm.Settings(max_iterations=0)
    with pytest.raises(cadmm.InvalidSettingError):
        cadmm.Settings(max_iterations=-5)
    with pytest.raises(cadmm.InvalidSettingError):
        cadmm.Settings(time_limit=-1.0)
    with pytest.raises(cadmm.InvalidSettingError):
        cadmm.Settings(threads=0)
    with pytest.raises(TypeError):
        cadmm.Settings(1e-8)  # keywords only


def test_solver_inputs():
    s = cadmm.Solver(cadmm.GlobalProblem(I3, I3, F, Z, [0.5]))
    with pytest.raises(cadmm.DimensionError):
        s.warm_start(np.zeros(2))
    with pytest.raises(cadmm.InvalidValueError):
        s.warm_start([np.nan, 0.0, 0.0])
    with pytest.raises(cadmm.DimensionError):
        s.update_values(f=[1.0])
    with pytest.raises(TypeError):
        cadmm.Solver("not a problem")
    with pytest.raises(cadmm.DimensionError):
        cadmm.error(cadmm.GlobalProblem(I3, I3, F, Z, [0.5]), np.zeros(3))  # v missing


def test_files(tmp_path):
    pytest.importorskip("h5py")
    with pytest.raises(cadmm.IoError):
        cadmm.read_fclib(tmp_path / "missing.hdf5")
    import h5py

    with h5py.File(tmp_path / "empty.hdf5", "w"):
        pass
    with pytest.raises(cadmm.IoError):
        cadmm.read_fclib(tmp_path / "empty.hdf5")
