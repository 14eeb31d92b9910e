# Type stub of the Rust extension module aerodelta._core (crates/py_bindings).
# Keep in step with the #[pymethods] there; tests/test_stub.py checks names.
import numpy as np
import numpy.typing as npt

__version__: str

class AerodeltaError(Exception): ...
class InvalidInputError(AerodeltaError): ...
class OutOfRangeError(AerodeltaError): ...
class TooLittleDataError(AerodeltaError): ...
class NoConvergenceError(AerodeltaError): ...
class ParseError(AerodeltaError): ...
class AeroIOError(AerodeltaError): ...

class Table:
    def __init__(
        self,
        names: list[str],
        breakpoints: list[list[float]],
        values: npt.NDArray[np.float64],
        below: list[str],
        above: list[str],
        mins: list[float | None],
        maxs: list[float | None],
    ) -> None: ...
    @property
    def ndim(self) -> int: ...
    @property
    def names(self) -> list[str]: ...
    @property
    def breakpoints(self) -> list[list[float]]: ...
    def values(self) -> npt.NDArray[np.float64]: ...
    def eval_point(self, x: list[float]) -> float: ...
    def eval_columns(self, columns: list[npt.NDArray[np.float64]]) -> npt.NDArray[np.float64]: ...
    def eval_rows(self, points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...

# --- preprocessing (crates/py_bindings/src/preprocess.rs) ---
def smooth(
    x: npt.NDArray[np.float64], dt: float
) -> tuple[npt.NDArray[np.float64], float, float]: ...
def smooth_deriv(
    x: npt.NDArray[np.float64], dt: float
) -> tuple[npt.NDArray[np.float64], float]: ...
def local_poly_deriv(
    x: npt.NDArray[np.float64], dt: float, half_window: int, order: int
) -> npt.NDArray[np.float64]: ...
def accel_to_cg(
    accel: list[npt.NDArray[np.float64]],
    rates: list[npt.NDArray[np.float64]],
    rate_derivs: list[npt.NDArray[np.float64]],
    position_m: list[float] | tuple[float, float, float],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def vanes_to_cg(
    alpha_vane: npt.NDArray[np.float64],
    beta_vane: npt.NDArray[np.float64],
    tas: npt.NDArray[np.float64],
    rates: list[npt.NDArray[np.float64]],
    alpha_vane_m: list[float] | tuple[float, float, float],
    beta_vane_m: list[float] | tuple[float, float, float],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def preprocess_columns() -> tuple[list[str], list[str], list[str]]: ...
def preprocess_batch(
    columns: list[npt.NDArray[np.float64]],
    offsets: list[int],
    mass_geometry: list[float],
    prop_h_per_rpm: float,
    accel_m: list[float],
    alpha_vane_m: list[float],
    beta_vane_m: list[float],
    smooth: bool = True,
) -> tuple[list[npt.NDArray[np.float64]], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def compat_check(
    t: npt.NDArray[np.float64],
    accel: list[npt.NDArray[np.float64]],
    rates: list[npt.NDArray[np.float64]],
    tas: npt.NDArray[np.float64],
    alpha: npt.NDArray[np.float64],
    beta: npt.NDArray[np.float64],
    euler: list[npt.NDArray[np.float64]],
    max_iter: int = 20,
) -> dict[str, object]: ...
