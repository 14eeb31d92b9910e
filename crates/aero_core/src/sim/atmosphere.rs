//! International Standard Atmosphere (ICAO Doc 7488 / ISO 2533) from sea level
//! to 20 km geopotential altitude: the troposphere (lapse rate −6.5 K/km to
//! 11 km) and the isothermal lower stratosphere (216.65 K, 11-20 km).

/// Sea-level standard temperature, K.
pub const T0: f64 = 288.15;
/// Sea-level standard pressure, Pa.
pub const P0: f64 = 101_325.0;
/// Sea-level standard density, kg/m³.
pub const RHO0: f64 = 1.225;
/// Specific gas constant of dry air, J/(kg K).
pub const R_AIR: f64 = 287.052_87;
/// Ratio of specific heats of air.
pub const GAMMA: f64 = 1.4;
/// Standard gravity, m/s².
pub const G0: f64 = 9.806_65;
/// Troposphere lapse rate, K/m.
pub const LAPSE: f64 = -0.0065;
/// Tropopause altitude, m.
pub const H_TROPOPAUSE: f64 = 11_000.0;
/// Upper validity limit of this model, m.
pub const H_MAX: f64 = 20_000.0;

/// Air properties at one altitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Air {
    /// Temperature, K.
    pub temperature_k: f64,
    /// Static pressure, Pa.
    pub pressure_pa: f64,
    /// Density, kg/m³.
    pub density_kgm3: f64,
    /// Speed of sound, m/s.
    pub sound_speed_mps: f64,
}

/// ISA at geopotential altitude `h_m` (m), clamped to [−500 m, 20 km].
pub fn isa(h_m: f64) -> Air {
    let h = h_m.clamp(-500.0, H_MAX);
    let (t, p) = if h <= H_TROPOPAUSE {
        let t = T0 + LAPSE * h;
        (t, P0 * (t / T0).powf(-G0 / (LAPSE * R_AIR)))
    } else {
        let t11 = T0 + LAPSE * H_TROPOPAUSE;
        let p11 = P0 * (t11 / T0).powf(-G0 / (LAPSE * R_AIR));
        (t11, p11 * (-G0 * (h - H_TROPOPAUSE) / (R_AIR * t11)).exp())
    };
    Air {
        temperature_k: t,
        pressure_pa: p,
        density_kgm3: p / (R_AIR * t),
        sound_speed_mps: (GAMMA * R_AIR * t).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values: ICAO standard atmosphere table (Doc 7488, geopotential altitude).
    #[test]
    fn matches_standard_table() {
        let rows = [
            (0.0, 288.15, 101_325.0, 1.2250, 340.29),
            (1000.0, 281.65, 89_874.6, 1.1116, 336.43),
            (3000.0, 268.65, 70_108.5, 0.909_12, 328.58),
            (5000.0, 255.65, 54_019.9, 0.736_12, 320.53),
            (11_000.0, 216.65, 22_632.0, 0.363_92, 295.07),
            (15_000.0, 216.65, 12_045.0, 0.193_67, 295.07),
            (20_000.0, 216.65, 5_474.9, 0.088_035, 295.07),
        ];
        for (h, t, p, rho, a) in rows {
            let air = isa(h);
            assert!((air.temperature_k - t).abs() < 0.01, "T at {h}");
            assert!(
                (air.pressure_pa / p - 1.0).abs() < 2e-4,
                "p at {h}: {}",
                air.pressure_pa
            );
            assert!(
                (air.density_kgm3 / rho - 1.0).abs() < 3e-4,
                "rho at {h}: {}",
                air.density_kgm3
            );
            assert!((air.sound_speed_mps - a).abs() < 0.02, "a at {h}");
        }
    }
}
