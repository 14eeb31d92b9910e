//! Per-maneuver mass properties of the virtual flight test: mass, CG position
//! and inertia tensor drawn for each maneuver (a flight test's fuel burn,
//! ballast and crew), and the moment transfer from the aircraft's datum to the
//! actual CG.
//!
//! Frame and datum: body axes (x forward, y right wing, z down), metres, from
//! the aircraft's **datum**, the nominal CG of `aircraft.toml` (the origin its
//! `[sensors]` positions are measured from). The truth aerodynamic model's
//! moments (thrust terms included) are about the datum: the datum is the moment
//! reference centre. With the CG at `d = r_cg − r_datum` the moments about the
//! CG are `M_cg = M_datum + (r_datum − r_cg) × F = M_datum − d × F`, with `F`
//! the aerodynamic + propulsive force (gravity acts at the CG).
//!
//! Static stability: the ADX-37's C_mα = −0.75/rad with C_Lα = 5.2/rad puts the
//! neutral point 0.75/5.2 = 14.4 % c̄ (0.30 m) aft of the datum. Measured on the
//! trim (flaps 0, 75 → 85 m/s level, 3000 m), the elevator's gradient dδe/dC_L is
//! −4.7° per unit C_L at the datum, −1.9° 0.195 m aft and crosses zero 0.32 m aft
//! (the power-on neutral point). A CG `d_x` forward (positive) adds `d_x/c̄ · C_N` of
//! nose-down moment, aft removes it; [`MAX_CG_X_RANGE_M`] keeps the aft-most draw
//! 5 % c̄ ahead of the neutral point.

use nalgebra::Vector3;

use crate::aircraft::turboprop::AircraftRef;
use crate::error::{AeroError, Result};
use crate::sim::rng::Stream;

/// Largest total CG range along x, m: draws within ±0.195 m = ±9.3 % c̄ of the
/// datum, so the aft-most CG keeps a static margin of 14.4 − 9.3 ≈ 5 % c̄ (the
/// "10 % c̄ CG shift", 0.21 m, is well inside). The pilot model flies the quick
/// campaign to the stall and back with the CG fixed anywhere from 0.3 m aft to
/// 0.3 m forward; 0.35 m forward, 2 of 40 accelerated stalls stay below n = 1.3
/// (`docs/aircraft.md`): the limit is the static margin, not the pilot.
pub const MAX_CG_X_RANGE_M: f64 = 0.39;
/// Largest total CG range along y, m (±0.05 m: a lateral CG offset rolls the
/// aircraft by `d_y · L`, C_l = d_y C_L / b ≈ ±0.004 at C_L,max, beyond the
/// `lateral_asymmetry` effect's 0.003 where the ailerons have lost their
/// authority; at a fixed 0.05 m one pusher stall in 40 ends on a wing drop
/// before the pusher fires, at 0.1 m 2-3 in 40 miss the stall criteria).
pub const MAX_CG_Y_RANGE_M: f64 = 0.1;
/// Largest total CG range along z, m (±0.25 m: a vertical offset couples drag
/// and thrust into pitch and side force into roll; the quick campaign flies
/// unchanged with the CG fixed 0.25 m above or 0.5 m below the datum).
pub const MAX_CG_Z_RANGE_M: f64 = 0.5;
/// Relative ranges of the mass and inertias must stay below this (±100 %: a
/// mass or inertia of zero or less has no meaning).
pub const MAX_RELATIVE_RANGE: f64 = 2.0;

/// How the mass properties vary from maneuver to maneuver: total ranges of
/// uniform draws about the nominal values of `aircraft.toml`.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MassVariation {
    /// Total CG range per body axis (x forward, y right, z down), m: the CG is
    /// uniform within ±range/2 of the datum on each axis.
    pub cg_range_m: [f64; 3],
    /// Total relative mass range, -: mass = nominal · (1 + U(−range/2, +range/2)).
    pub mass_range: f64,
    /// Total relative inertia range, -: I_xx, I_yy, I_zz and I_xz are each
    /// scaled by their own 1 + U(−range/2, +range/2).
    pub inertia_range: f64,
}

/// The mass properties one maneuver is flown with.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MassProperties {
    /// Mass, kg.
    pub mass_kg: f64,
    /// CG position from the datum, body axes, m.
    pub cg_m: [f64; 3],
    /// Roll inertia about the CG, kg m².
    pub ixx: f64,
    /// Pitch inertia about the CG, kg m².
    pub iyy: f64,
    /// Yaw inertia about the CG, kg m².
    pub izz: f64,
    /// Product of inertia I_xz about the CG, kg m² (Etkin's sign: the tensor holds −I_xz).
    pub ixz: f64,
}

impl MassProperties {
    /// The nominal properties of `ac`: its mass and inertias, the CG at the datum.
    pub fn nominal(ac: &AircraftRef) -> Self {
        MassProperties {
            mass_kg: ac.mass_kg,
            cg_m: [0.0; 3],
            ixx: ac.ixx,
            iyy: ac.iyy,
            izz: ac.izz,
            ixz: ac.ixz,
        }
    }

    /// The CG offset from the datum `d = r_cg − r_datum`, m.
    pub fn cg_offset(&self) -> Vector3<f64> {
        Vector3::new(self.cg_m[0], self.cg_m[1], self.cg_m[2])
    }
}

impl MassVariation {
    /// Refuse ranges without meaning: not finite, negative, a relative range of
    /// [`MAX_RELATIVE_RANGE`] or more, a CG range beyond the `MAX_CG_*_RANGE_M` limits.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the field, the value and the limit.
    pub fn validate(&self) -> Result<()> {
        let place = "campaign mass_properties";
        let limits = [MAX_CG_X_RANGE_M, MAX_CG_Y_RANGE_M, MAX_CG_Z_RANGE_M];
        for ((axis, &r), lim) in ["x", "y", "z"].iter().zip(&self.cg_range_m).zip(limits) {
            if !(r.is_finite() && r >= 0.0) {
                return Err(AeroError::invalid(
                    place,
                    format!("cg_range_m {axis} = {r}: give a finite total range >= 0 m"),
                ));
            }
            if r > lim {
                let why = if *axis == "x" {
                    format!(
                        " (±{:.3} m: the aft-most CG keeps 5 % c̄ of the 14.4 % c̄ static \
                         margin, the neutral point is 0.30 m aft of the datum)",
                        lim / 2.0
                    )
                } else {
                    String::new()
                };
                return Err(AeroError::invalid(
                    place,
                    format!(
                        "cg_range_m {axis} = {r} m is beyond the {lim} m the ADX-37 stays \
                         stable and flyable with{why}; give at most {lim}"
                    ),
                ));
            }
        }
        for (name, r) in [
            ("mass_range", self.mass_range),
            ("inertia_range", self.inertia_range),
        ] {
            if !(r.is_finite() && (0.0..MAX_RELATIVE_RANGE).contains(&r)) {
                return Err(AeroError::invalid(
                    place,
                    format!(
                        "{name} = {r}: give a total relative range >= 0 and < {MAX_RELATIVE_RANGE} \
                         (0.1 = ±5 %)"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The properties of one maneuver: uniform draws from `stream` of `seed`,
    /// in a fixed order (mass, CG x, y, z, I_xx, I_yy, I_zz, I_xz), about the
    /// nominal values of `ac`. Zero ranges give the nominal values exactly.
    pub fn draw(&self, ac: &AircraftRef, seed: u64, stream: u64) -> MassProperties {
        let mut s = Stream::new(seed, stream);
        let mut centred = |range: f64| range * (s.uniform() - 0.5);
        let mass = 1.0 + centred(self.mass_range);
        let cg_m = [
            centred(self.cg_range_m[0]),
            centred(self.cg_range_m[1]),
            centred(self.cg_range_m[2]),
        ];
        let ri = self.inertia_range;
        let scale = [
            1.0 + centred(ri),
            1.0 + centred(ri),
            1.0 + centred(ri),
            1.0 + centred(ri),
        ];
        MassProperties {
            mass_kg: ac.mass_kg * mass,
            cg_m,
            ixx: ac.ixx * scale[0],
            iyy: ac.iyy * scale[1],
            izz: ac.izz * scale[2],
            ixz: ac.ixz * scale[3],
        }
    }
}

/// Moment about the CG from the moment about the datum: `M_cg = M_datum − d × F`
/// with `d = r_cg − r_datum` and `F` the aerodynamic + propulsive force, N m.
#[inline]
pub fn moment_about_cg(
    m_datum: &Vector3<f64>,
    force: &Vector3<f64>,
    d: &Vector3<f64>,
) -> Vector3<f64> {
    m_datum - d.cross(force)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::turboprop::adx37;

    #[test]
    fn moment_transfer_closed_form() {
        // d × F written out component by component
        let m = Vector3::new(1.0e3, -2.0e4, 5.0e2);
        let f = Vector3::new(3.0e3, -1.2e3, -1.5e5);
        let d = Vector3::new(-0.1, 0.04, 0.08);
        let got = moment_about_cg(&m, &f, &d);
        let want = [
            m.x - (d.y * f.z - d.z * f.y),
            m.y - (d.z * f.x - d.x * f.z),
            m.z - (d.x * f.y - d.y * f.x),
        ];
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() < 1e-9,
                "{k}: {} vs {}",
                got[k],
                want[k]
            );
        }
        // an aft CG (d_x < 0) under lift (F_z < 0) pitches the nose up: less stable
        assert!(got.y > m.y);
    }

    #[test]
    fn draws_lie_within_the_ranges_are_seeded_and_zero_ranges_are_nominal() {
        let ac = adx37();
        let v = MassVariation {
            cg_range_m: [0.21, 0.05, 0.1],
            mass_range: 0.1,
            inertia_range: 0.1,
        };
        let mut lo = [f64::INFINITY; 8];
        let mut hi = [f64::NEG_INFINITY; 8];
        for seed in 0..2000 {
            let p = v.draw(&ac, seed, 6);
            let vals = [
                p.mass_kg / ac.mass_kg - 1.0,
                p.cg_m[0],
                p.cg_m[1],
                p.cg_m[2],
                p.ixx / ac.ixx - 1.0,
                p.iyy / ac.iyy - 1.0,
                p.izz / ac.izz - 1.0,
                p.ixz / ac.ixz - 1.0,
            ];
            for k in 0..8 {
                lo[k] = lo[k].min(vals[k]);
                hi[k] = hi[k].max(vals[k]);
            }
        }
        let half = [0.05, 0.105, 0.025, 0.05, 0.05, 0.05, 0.05, 0.05];
        for k in 0..8 {
            assert!(lo[k] >= -half[k] - 1e-12 && hi[k] <= half[k] + 1e-12, "{k}");
            // 2000 uniform draws fill the range to within 1 % of each end
            assert!(lo[k] < -0.98 * half[k] && hi[k] > 0.98 * half[k], "{k}");
        }
        assert_eq!(v.draw(&ac, 7, 6), v.draw(&ac, 7, 6));
        assert_ne!(v.draw(&ac, 7, 6), v.draw(&ac, 8, 6));
        let zero = MassVariation::default().draw(&ac, 7, 6);
        assert_eq!(zero, MassProperties::nominal(&ac));
    }

    #[test]
    fn meaningless_ranges_are_refused() {
        let ok = MassVariation {
            cg_range_m: [MAX_CG_X_RANGE_M, 0.05, 0.1],
            mass_range: 0.1,
            inertia_range: 0.1,
        };
        assert!(ok.validate().is_ok());
        let bad = [
            MassVariation {
                cg_range_m: [-0.1, 0.0, 0.0],
                ..ok
            },
            MassVariation {
                cg_range_m: [MAX_CG_X_RANGE_M + 0.01, 0.0, 0.0],
                ..ok
            },
            MassVariation {
                cg_range_m: [0.0, f64::NAN, 0.0],
                ..ok
            },
            MassVariation {
                mass_range: 2.0,
                ..ok
            },
            MassVariation {
                inertia_range: 2.5,
                ..ok
            },
            MassVariation {
                inertia_range: -0.1,
                ..ok
            },
        ];
        for b in bad {
            let e = b.validate().unwrap_err().to_string();
            assert!(
                e.contains("campaign mass_properties") && !e.contains('\n'),
                "{e}"
            );
        }
    }
}
