//! The representative aircraft: a high-wing, T-tail, twin-turboprop regional
//! airliner in the class of the thesis aircraft (a Bombardier turboprop with
//! flap settings 0, 5, 10, 15, 35: the Dash 8-100/200 family; ATR 42 is the
//! same class). Named "ADX-37" here; all values are representative, not a type's data.
//!
//! Reference values and their reasoning:
//! - Geometry: S = 54.35 m², b = 25.91 m (published Dash 8-100/200 wing area
//!   and span, Jane's All the World's Aircraft); c̄ = S/b = 2.10 m (straight,
//!   slightly tapered wing: the MAC is within a few % of the mean chord).
//! - Mass: 15 000 kg, a mid-weight stall-test condition (MTOW 15 650-16 470 kg,
//!   OEW about 10 500 kg).
//! - Inertias from Roskam's non-dimensional radii of gyration for twin
//!   turboprops (Airplane Design Part V, Table 10.1: R̄x = 0.25, R̄y = 0.38,
//!   R̄z = 0.39): I_xx = m (b R̄x/2)² ≈ 1.57e5, I_yy = m (L R̄y/2)² with length
//!   L = 22.25 m ≈ 2.68e5, I_zz = m (((b+L)/2) R̄z/2)² ≈ 3.31e5 kg m²; I_xz is
//!   small for a straight high wing, 1.2e4 kg m² (≈ 8 % of I_xx).
//! - Propulsion: two PW120-class engines of 1 490 kW (2 000 shp), flat-rated,
//!   four-blade 3.96 m propellers at 1 020 rpm (governed climb/cruise speed);
//!   propeller polar inertia ≈ 60 kg m² (four ≈ 25 kg blades of radius 1.98 m:
//!   4 · m R²/3 ≈ 131 kg m² for uniform rods, halved for the blade taper and
//!   root mass concentration). Both propellers turn the same way (as on the
//!   Dash 8), so their gyroscopic moments add (thesis Eq. 3.3). Engines at
//!   y = ±4.1 m, thrust line 0.4 m above the CG.
//! - Sensors (flight-test boom and nose installation): alpha and beta vanes on a
//!   nose boom 9.5 m ahead of the CG, the beta vane 0.3 m above it; the
//!   accelerometer package in the cabin 1.2 m aft, 0.25 m right, 0.6 m below
//!   the CG (a realistic non-CG location, so the ingestion's correction matters).

/// Reference values of the representative aircraft (SI units).
#[derive(Debug, Clone, PartialEq)]
pub struct AircraftRef {
    /// Display name.
    pub name: &'static str,
    /// Wing area S, m².
    pub s_m2: f64,
    /// Span b, m.
    pub b_m: f64,
    /// Mean aerodynamic chord c̄, m.
    pub cbar_m: f64,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Roll inertia, kg m².
    pub ixx: f64,
    /// Pitch inertia, kg m².
    pub iyy: f64,
    /// Yaw inertia, kg m².
    pub izz: f64,
    /// Product of inertia I_xz, kg m².
    pub ixz: f64,
    /// Number of engines.
    pub n_engines: usize,
    /// Propeller polar inertia per propeller, kg m².
    pub prop_inertia: f64,
    /// Governed propeller speed, rpm.
    pub prop_rpm: f64,
    /// Engine lateral arm (|y| of each thrust line), m.
    pub engine_y_m: f64,
    /// Thrust line height above the CG, m.
    pub thrust_line_above_cg_m: f64,
    /// Maximum shaft power per engine (sea level), W.
    pub max_power_w: f64,
    /// Accelerometer position relative to the datum (the nominal CG), body axes, m.
    pub accel_m: [f64; 3],
    /// Alpha vane position relative to the datum (the nominal CG), m.
    pub alpha_vane_m: [f64; 3],
    /// Beta vane position relative to the datum (the nominal CG), m.
    pub beta_vane_m: [f64; 3],
    /// Flap settings, deg.
    pub flaps_deg: [f64; 5],
}

/// The representative aircraft's reference values (see module docs).
pub fn adx37() -> AircraftRef {
    AircraftRef {
        name: "ADX-37 representative twin turboprop",
        s_m2: 54.35,
        b_m: 25.91,
        cbar_m: 2.10,
        mass_kg: 15_000.0,
        ixx: 1.57e5,
        iyy: 2.68e5,
        izz: 3.31e5,
        ixz: 1.2e4,
        n_engines: 2,
        prop_inertia: 60.0,
        prop_rpm: 1020.0,
        engine_y_m: 4.1,
        thrust_line_above_cg_m: 0.4,
        max_power_w: 1.49e6,
        accel_m: [-1.2, 0.25, 0.6],
        alpha_vane_m: [9.5, 0.0, 0.0],
        beta_vane_m: [9.5, 0.0, -0.3],
        flaps_deg: [0.0, 5.0, 10.0, 15.0, 35.0],
    }
}

impl AircraftRef {
    /// Aspect ratio `A = b²/S`.
    pub fn aspect_ratio(&self) -> f64 {
        self.b_m * self.b_m / self.s_m2
    }

    /// The aircraft reference file (the campaign contract's `aircraft.toml`).
    pub fn to_toml(&self) -> String {
        let v = |a: [f64; 3]| format!("[{:?}, {:?}, {:?}]", a[0], a[1], a[2]);
        format!(
            "# Representative aircraft of the aerodelta virtual flight test (see docs/aircraft.md).\n\
             name = \"{}\"\n\n[geometry]\nS_m2 = {:?}\nb_m = {:?}\ncbar_m = {:?}\n\n\
             [mass]\nmass_kg = {:?}\nIxx_kgm2 = {:?}\nIyy_kgm2 = {:?}\nIzz_kgm2 = {:?}\nIxz_kgm2 = {:?}\n\n\
             [propulsion]\nn_engines = {}\nprop_inertia_kgm2 = {:?}\nprop_rotation = \"ccw\"\n\
             prop_rpm_channel = \"prop_rpm\"\nprop_rpm_fixed = {:?}\n\n\
             [sensors]\naccel_m = {}\nalpha_vane_m = {}\nbeta_vane_m = {}\n\n\
             [simulator]\nbuiltin = \"adx37\"  # flown on the built-in virtual aircraft: \
             its qualified model is the simulator\n",
            self.name,
            self.s_m2,
            self.b_m,
            self.cbar_m,
            self.mass_kg,
            self.ixx,
            self.iyy,
            self.izz,
            self.ixz,
            self.n_engines,
            self.prop_inertia,
            self.prop_rpm,
            v(self.accel_m),
            v(self.alpha_vane_m),
            v(self.beta_vane_m),
        )
    }
}
