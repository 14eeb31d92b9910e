# Type stub of the Rust extension module aerodelta._core (crates/py_bindings).
# Keep in step with the #[pymethods] there; tests/test_stub.py checks names.
from typing import Any

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

class DeltaModel:
    @staticmethod
    def from_json(text: str, source: str) -> DeltaModel: ...
    @staticmethod
    def load(path: str) -> DeltaModel: ...
    def to_json(self) -> str: ...
    def save(self, path: str) -> None: ...
    @property
    def coefficient_names(self) -> list[str]: ...
    @property
    def input_columns(self) -> list[str]: ...
    def parameter(
        self, coefficient: str, term: str, flap_deg: float, alpha_deg: float
    ) -> float: ...
    def in_envelope(
        self,
        flap_deg: npt.NDArray[np.float64],
        alpha_deg: npt.NDArray[np.float64],
        beta_deg: npt.NDArray[np.float64],
    ) -> npt.NDArray[np.bool_] | None: ...
    def eval_columns(
        self, coefficient: str, columns: dict[str, npt.NDArray[np.float64]], n: int
    ) -> tuple[
        npt.NDArray[np.float64], npt.NDArray[np.float64], dict[str, npt.NDArray[np.float64]]
    ]: ...

class SmoothingSpline:
    def p(self) -> float: ...
    def breaks(self) -> npt.NDArray[np.float64]: ...
    def coefs(self) -> npt.NDArray[np.float64]: ...
    def eval(
        self, x: npt.NDArray[np.float64], nu: int, extrapolate: str
    ) -> npt.NDArray[np.float64]: ...
    def to_table(self, name: str, grid: list[float], extrapolate: str) -> Table: ...

def smoothing_spline(
    x: npt.NDArray[np.float64],
    y: npt.NDArray[np.float64],
    weights: npt.NDArray[np.float64] | None = None,
    p: float | None = None,
    normalized: bool = False,
) -> SmoothingSpline: ...
def merge_sites(
    x: npt.NDArray[np.float64],
    y: npt.NDArray[np.float64],
    weights: npt.NDArray[np.float64] | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...

class AlphaBins:
    def required_points(self) -> int: ...
    def required_maneuvers(self) -> int: ...
    def edges(self) -> npt.NDArray[np.float64]: ...
    def counts(self) -> npt.NDArray[np.uintp]: ...
    def maneuvers(self) -> npt.NDArray[np.uintp] | None: ...
    def index(self) -> npt.NDArray[np.int64]: ...
    def underfilled(self) -> npt.NDArray[np.bool_]: ...

def partition_alpha(
    alpha_deg: npt.NDArray[np.float64],
    n_params: int,
    width_deg: float = 0.2,
    min_points_per_param: int = 10,
    maneuver_id: npt.NDArray[np.uint64] | None = None,
    min_maneuvers: int = 1,
    alpha_range: tuple[float, float] | None = None,
    max_width_deg: float | None = None,
    anchor_deg: float = 0.0,
) -> AlphaBins: ...

class DaveModel:
    def __init__(self, path: str) -> None: ...
    @staticmethod
    def from_string(text: str, name: str) -> DaveModel: ...
    def name(self) -> str: ...
    def inputs(self) -> list[str]: ...
    def outputs(self) -> list[str]: ...
    def n_shots(self) -> int: ...
    def variables(
        self,
    ) -> list[tuple[str, str, str, bool, bool, float | None, float | None, float | None]]: ...
    def uncertainties(
        self,
    ) -> list[tuple[str, str, str, float, list[list[float]], list[str], int]]: ...
    def evaluate(
        self,
        inputs: dict[str, npt.NDArray[np.float64]],
        outputs: list[str] | None = None,
    ) -> dict[str, npt.NDArray[np.float64]]: ...
    def run_checks(
        self,
    ) -> list[tuple[str, str, str, str, str, float, float, float, bool]]: ...

def daveml_write(path: str, spec_json: str) -> DaveModel: ...
def daveml_to_xml(spec_json: str) -> str: ...
def daveml_merge_xml(base_text: str, base_name: str, spec_json: str) -> str: ...

# Virtual flight test (crates/py_bindings/src/sim.rs)
def sim_run_campaign(spec_json: str) -> list[dict[str, object]]: ...
def sim_plan(spec_json: str) -> str: ...
def sim_default_spec() -> str: ...
def sim_replay(
    flap_deg: float,
    effects_json: str,
    x0: list[float],
    dt: float,
    controls_deg: npt.NDArray[np.float64],
    ct: npt.NDArray[np.float64],
    rolloff_seed: int | None = None,
) -> npt.NDArray[np.float64]: ...
def sim_replay_extended(
    flap_deg: float,
    model: DeltaModel,
    x0: list[float],
    dt: float,
    controls_deg: npt.NDArray[np.float64],
    ct: npt.NDArray[np.float64],
    rolloff_seed: int | None = None,
    lateral_delta: bool = True,
) -> npt.NDArray[np.float64]: ...
def sim_closed_loop(
    record: npt.NDArray[np.float64],
    x0: list[float],
    options_json: str,
    model: DeltaModel | None = None,
    kirchhoff: list[float] | None = None,
    effects_json: str | None = None,
    kirchhoff_drag: list[float] | None = None,
    x0_knots: list[float] | None = None,
    x0_values: list[float] | None = None,
) -> tuple[npt.NDArray[np.float64], str]: ...
def sim_closed_loop_columns() -> tuple[list[str], list[str]]: ...
def sim_replay_daveml(
    model: DaveModel,
    aircraft: list[float],
    flap_deg: float,
    x0: list[float],
    dt: float,
    controls_deg: npt.NDArray[np.float64],
    ct: npt.NDArray[np.float64],
    delta: DeltaModel | None = None,
) -> npt.NDArray[np.float64]: ...
def sim_trim(flap_deg: float, v: float, h: float) -> tuple[list[float], list[float], float]: ...
def sim_effect_library() -> str: ...
def sim_aircraft_toml() -> str: ...
def sim_qualified_tables() -> tuple[
    list[tuple[str, list[str], list[list[float]], npt.NDArray[np.float64]]], str
]: ...
def sim_rolloff_draws(
    flap_deg: float, seed: int, n: int, stream: int = 0
) -> dict[str, npt.NDArray[np.float64]]: ...
def sim_rolloff_config() -> str: ...

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
    cg_m: list[float] = ...,
    moment_ref_m: list[float] = ...,
    masses: npt.NDArray[np.float64] | None = None,
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
    scale_factors: bool = False,
    r_alpha: list[float] = ...,
    r_beta: list[float] = ...,
    flank: bool = False,
    gusts: bool = False,
) -> dict[str, object]: ...
def plausibility_check(
    offsets: list[int],
    t: npt.NDArray[np.float64],
    accel: list[npt.NDArray[np.float64]],
    rates: list[npt.NDArray[np.float64]],
    tas: npt.NDArray[np.float64],
    alpha: npt.NDArray[np.float64],
    beta: npt.NDArray[np.float64],
    euler: list[npt.NDArray[np.float64]],
    vane_offset: list[npt.NDArray[np.float64]],
    h: npt.NDArray[np.float64] | None,
    candidates: list[list[float]],
) -> list[dict[str, Any]]: ...

class OlsFit:
    @property
    def names(self) -> list[str]: ...
    @property
    def params(self) -> npt.NDArray[np.float64]: ...
    @property
    def std_err(self) -> npt.NDArray[np.float64]: ...
    @property
    def t_values(self) -> npt.NDArray[np.float64]: ...
    @property
    def p_values(self) -> npt.NDArray[np.float64]: ...
    @property
    def partial_f(self) -> npt.NDArray[np.float64]: ...
    @property
    def singular_values(self) -> npt.NDArray[np.float64]: ...
    @property
    def singular_values_scaled(self) -> npt.NDArray[np.float64]: ...
    @property
    def vif(self) -> npt.NDArray[np.float64]: ...
    @property
    def cov(self) -> npt.NDArray[np.float64]: ...
    @property
    def cov_colored(self) -> npt.NDArray[np.float64] | None: ...
    @property
    def std_err_colored(self) -> npt.NDArray[np.float64] | None: ...
    @property
    def cov_cluster(self) -> npt.NDArray[np.float64] | None: ...
    @property
    def std_err_cluster(self) -> npt.NDArray[np.float64] | None: ...
    @property
    def dof_cluster(self) -> npt.NDArray[np.float64] | None: ...
    @property
    def n_clusters(self) -> int | None: ...
    @property
    def notes_cluster(self) -> list[str] | None: ...
    @property
    def r2(self) -> float: ...
    @property
    def r2_adj(self) -> float: ...
    @property
    def f_value(self) -> float: ...
    @property
    def f_pvalue(self) -> float: ...
    @property
    def s2(self) -> float: ...
    @property
    def rss(self) -> float: ...
    @property
    def tss(self) -> float: ...
    @property
    def fit_error_pct(self) -> float: ...
    @property
    def press(self) -> float: ...
    @property
    def pse(self) -> float: ...
    @property
    def condition_number(self) -> float: ...
    @property
    def condition_number_unscaled(self) -> float: ...
    @property
    def residual_mean(self) -> float: ...
    @property
    def rank(self) -> int: ...
    @property
    def nobs(self) -> int: ...
    @property
    def dof(self) -> int: ...
    @property
    def df_model(self) -> int: ...
    @property
    def rank_deficient(self) -> bool: ...
    @property
    def dependencies(self) -> list[tuple[float, list[int], list[float], list[float]]]: ...
    @property
    def identifiable(self) -> list[bool]: ...
    @property
    def notes(self) -> list[str]: ...
    @property
    def const_column(self) -> int | None: ...
    @property
    def dropped_rows(self) -> list[int]: ...

def ols(
    x: npt.NDArray[np.float64],
    z: npt.NDArray[np.float64],
    rows: npt.NDArray[np.uint64] | None = None,
    names: list[str] | None = None,
    drop_nan: bool = False,
    colored: bool = True,
    max_lag: int | None = None,
    min_norm: bool = False,
    collinear_cond: float = 1e6,
    groups: npt.NDArray[np.uint64] | None = None,
) -> OlsFit: ...
def student_t_cdf(t: float, df: float) -> float: ...
def student_t_ppf(prob: float, df: float) -> float: ...
def f_cdf(f: float, d1: float, d2: float) -> float: ...
def f_sf(f: float, d1: float, d2: float) -> float: ...
def beta_inc_reg(a: float, b: float, x: float) -> float: ...
def qualified_lateral_adx37(
    columns: dict[str, npt.NDArray[np.float64]],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def qualified_longitudinal_adx37(
    columns: dict[str, npt.NDArray[np.float64]],
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
]: ...
def goman_khrabrov_core_names() -> list[str]: ...
def goman_khrabrov_outputs(
    core: dict[str, float],
    knots: list[float],
    values: list[float],
    t: npt.NDArray[np.float64],
    alpha: npt.NDArray[np.float64],
    alpha_dot: npt.NDArray[np.float64],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def goman_khrabrov_static(
    core: dict[str, float], knots: list[float], values: list[float], alpha: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def goman_khrabrov_cl_max(
    core: dict[str, float], knots: list[float], values: list[float]
) -> tuple[float, float]: ...
def goman_khrabrov_weights(
    knots: list[float], alpha: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]: ...
def output_error_goman_khrabrov(
    t: list[npt.NDArray[np.float64]],
    alpha: list[npt.NDArray[np.float64]],
    alpha_dot: list[npt.NDArray[np.float64]],
    cl: list[npt.NDArray[np.float64]],
    cm: list[npt.NDArray[np.float64]] | None,
    core: dict[str, float],
    knots: list[float],
    values: list[float],
    fixed: list[str] = ...,
    max_iter: int = ...,
    tol: float = ...,
    max_lag: int | None = ...,
) -> dict[str, Any]: ...
def kirchhoff_param_names() -> list[str]: ...
def kirchhoff_truth_params(flap_deg: float) -> dict[str, float]: ...
def kirchhoff_truth_drag(flap_deg: float) -> dict[str, float]: ...
def kirchhoff_drag_names() -> list[str]: ...
def kirchhoff_drag_point(
    drag: dict[str, float], cl: npt.NDArray[np.float64], x: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]: ...
def kirchhoff_cl_max(params: dict[str, float]) -> tuple[float, float]: ...
def kirchhoff_outputs(
    params: dict[str, float],
    t: npt.NDArray[np.float64],
    alpha: npt.NDArray[np.float64],
    alpha_dot: npt.NDArray[np.float64],
    sensitivities: bool = False,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64] | None,
    npt.NDArray[np.float64] | None,
]: ...
def output_error_kirchhoff(
    t: list[npt.NDArray[np.float64]],
    alpha: list[npt.NDArray[np.float64]],
    alpha_dot: list[npt.NDArray[np.float64]],
    cl: list[npt.NDArray[np.float64]],
    cm: list[npt.NDArray[np.float64]] | None = None,
    start: dict[str, float] | None = None,
    fixed: list[str] = ...,
    max_iter: int = 60,
    tol: float = 1e-9,
    max_lag: int | None = None,
) -> dict[str, Any]: ...
def identify_flap(
    regressors: list[tuple[str, str]],
    columns: dict[str, npt.NDArray[np.float64]],
    z: npt.NDArray[np.float64],
    alpha_deg: npt.NDArray[np.float64],
    maneuver: npt.NDArray[np.uint64],
    width_deg: float,
    min_points_per_param: int,
    min_maneuvers: int,
    max_width_deg: float | None,
    colored: bool,
    min_excitation: float,
    p: float,
    weighted: bool,
    grid_step_deg: float,
    alpha_max_deg: float,
    min_identified_bins: int,
    selection: str | None,
    f_in: float,
    f_out: float,
    forced: list[int],
    min_bins: int,
    folds: int,
    seed: int,
    extra: list[list[int]],
    bootstrap: int,
    level: float,
    t: npt.NDArray[np.float64] | None = None,
    band_hz: float | None = None,
    min_excitation_snr: float = 3.0,
    min_maneuvers_identified: int = 5,
    bootstrap_reselect: bool = False,
    max_vif: float = 10.0,
    prune_collinear: bool = True,
    nested_cv: bool = True,
    companions: list[tuple[int, int]] = ...,
) -> dict[str, Any]: ...

# sign-flip randomization counts on numpy's PCG64 stream (crates/py_bindings/src/signflip.rs)
def sign_flip_hits(
    weights: npt.NDArray[np.float64],
    w: float,
    state: int,
    inc: int,
    draws: int,
    per_call: int,
    tail: int,
    min_hits: int,
) -> tuple[int, int]: ...
def sign_flip_hits_many(
    weights: list[npt.NDArray[np.float64]],
    ws: list[float],
    states: list[int],
    incs: list[int],
    draws: int,
    per_call: int,
    tail: int,
    min_hits: int,
) -> list[tuple[int, int]]: ...

# the diagnosis's hat-basis cross-validation (crates/py_bindings/src/hatcv.rs); ``blocks`` is
# (diag, off, cross, glob, xty, yty, block_rows | None, lowrank | None, lowrank_of | None),
# ``layout`` (knots, aerodynamic regressors, global regressors)
_Blocks = tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.int64] | None,
    npt.NDArray[np.float64] | None,
    npt.NDArray[np.int64] | None,
]

def hat_held_out(
    blocks: _Blocks,
    layout: tuple[int, int, int],
    train_grams: npt.NDArray[np.float64],
    train_xty: npt.NDArray[np.float64],
    folds: npt.NDArray[np.int64],
    flap: npt.NDArray[np.int64],
    n_flaps: int,
    a_cols: npt.NDArray[np.int64],
    g_cols: npt.NDArray[np.int64],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def hat_solve(
    grams: npt.NDArray[np.float64],
    xtys: npt.NDArray[np.float64],
    layout: tuple[int, int, int],
    a_cols: npt.NDArray[np.int64],
    g_cols: npt.NDArray[np.int64],
) -> npt.NDArray[np.float64]: ...
def hat_quadratic_forms(
    blocks: _Blocks,
    layout: tuple[int, int, int],
    ms: npt.NDArray[np.int64],
    theta: npt.NDArray[np.float64],
    a_cols: npt.NDArray[np.int64],
    g_cols: npt.NDArray[np.int64],
) -> npt.NDArray[np.float64]: ...
def hat_fold_sums(
    blocks: _Blocks,
    layout: tuple[int, int, int],
    folds: npt.NDArray[np.int64],
    flap: npt.NDArray[np.int64],
    n_folds: int,
    n_flaps: int,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def hat_gram_sum(
    blocks: _Blocks,
    layout: tuple[int, int, int],
    ms: npt.NDArray[np.int64],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def hat_profile_out(
    blocks: _Blocks,
    layout: tuple[int, int, int],
    n_nuisance: int,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.int64],
]: ...
def hat_build(
    y: npt.NDArray[np.float64],
    maneuver: npt.NDArray[np.int64],
    alpha_deg: npt.NDArray[np.float64],
    aero: npt.NDArray[np.float64],
    globals: list[npt.NDArray[np.float64] | tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]],
    grid: tuple[float, float, int],
    n_maneuvers: int,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
]: ...

# roll-off detection and configurable runtime draws (crates/py_bindings/src/rolloff.rs)
def rolloff_detect_defaults() -> dict[str, float | bool]: ...
def rolloff_detect(
    t: npt.NDArray[np.float64],
    alpha_deg: npt.NDArray[np.float64],
    cl_residual: npt.NDArray[np.float64],
    da_deg: npt.NDArray[np.float64],
    quiet: list[tuple[str, npt.NDArray[np.float64], float]],
    config: dict[str, float | bool] | None = None,
) -> dict[str, object]: ...
def rolloff_sample_draws(
    config_json: str, flap_deg: float, seed: int, n: int, stream: int = 0
) -> dict[str, npt.NDArray[np.float64]]: ...

# roll-off events' nuisance columns and centres for the diagnosis (aero_core::rolloff_events,
# crates/py_bindings/src/rolloff.rs); rows[bounds[m]:bounds[m + 1]]: maneuver m's rows in time order
def rolloff_event_defaults() -> dict[str, Any]: ...
def rolloff_event_columns(
    rows: npt.NDArray[np.int64],
    bounds: npt.NDArray[np.int64],
    alpha_deg: npt.NDArray[np.float64],
    t: npt.NDArray[np.float64],
    maneuver: npt.NDArray[np.int64],
    centre_deg: npt.NDArray[np.float64],
    t_peak: npt.NDArray[np.float64],
    sigma_deg: float,
) -> tuple[list[npt.NDArray[np.int64]], list[npt.NDArray[np.float64]]]: ...
def rolloff_refine_centres(
    rows: npt.NDArray[np.int64],
    bounds: npt.NDArray[np.int64],
    alpha_deg: npt.NDArray[np.float64],
    t: npt.NDArray[np.float64],
    residual: npt.NDArray[np.float64],
    maneuver: npt.NDArray[np.int64],
    centre_deg: npt.NDArray[np.float64],
    t_peak: npt.NDArray[np.float64],
    sigma_deg: float,
) -> npt.NDArray[np.float64]: ...

# Monte Carlo of straight stalls (crates/py_bindings/src/rolloff.rs, aero_core::rolloff_mc)
def rolloff_monte_carlo(
    spec_json: str, threads: int | None = None
) -> dict[str, npt.NDArray[np.generic]]: ...
def rolloff_mc_default_spec() -> str: ...
def through_smoother(
    t: npt.NDArray[np.float64],
    maneuver: npt.NDArray[np.uint64],
    check_raw: npt.NDArray[np.float64],
    check_smoothed: npt.NDArray[np.float64],
    scale: npt.NDArray[np.float64],
    channels: list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]],
) -> tuple[list[npt.NDArray[np.float64]], tuple[int, int, int, int]]:
    """Each ``(reference, target)``: ``S_ref(target * scale) / scale`` per maneuver (the Wiener
    weights the smoother chooses for the raw reference), and the counts ``(matched,
    unsmoothed, changed, nonfinite)`` (``aero_core::preprocess::matched``)."""
    ...

def calibrate_chain(
    t: npt.NDArray[np.float64],
    maneuver: npt.NDArray[np.uint64],
    trusted: npt.NDArray[np.bool_],
    coefficients: list[
        tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], list[tuple[str, str]]]
    ],
    columns: dict[str, npt.NDArray[np.float64]],
    min_samples: int,
    min_maneuvers: int,
) -> list[
    tuple[
        str,
        tuple[float, float, float, float, int, int] | None,
        npt.NDArray[np.float64] | None,
    ]
]: ...
def kirchhoff_point(
    params: dict[str, float],
    alpha: npt.NDArray[np.float64],
    alpha_dot: npt.NDArray[np.float64],
    x: npt.NDArray[np.float64],
    knots: list[float] | None = None,
    values: list[float] | None = None,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
]: ...
