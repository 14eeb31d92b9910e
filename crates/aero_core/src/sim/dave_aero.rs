//! A DAVE-ML model as the simulator's aerodynamics: the user's own qualified model flown in
//! the 6-DOF loop (issue 19, item 5).
//!
//! Inputs are bound by `varID` to the loop's [`AeroInput`] with aerodelta's channel names
//! (those `aerodelta export-qualified` writes): `alpha_deg`/`alpha_rad`, `beta_deg`/`beta_rad`,
//! `phat`, `qhat`, `rhat`, `alphadot_hat` (α̇ c̄ / 2V), `alphadot_dps`, `betadot_dps`,
//! `da_deg`, `de_deg`/`de_rad`, `dr_deg`, `dsl_deg`, `dsr_deg`, `flap_deg`, `ct_left`,
//! `ct_right`, `tas_mps`, `mach`. Surfaces follow the loop's convention (Etkin, positive
//! aileron rolls left). An input with another `varID` is refused, unless it has a default
//! (`initialValue`), which it then keeps.
//!
//! Outputs: `CY`, `Cl`, `Cm`, `Cn` and the longitudinal forces either as body-axis `CX`, `CZ`
//! (total: thrust included) or as aerodynamic lift and drag `CL`, `CD`, to which the thrust
//! `C_T,left + C_T,right` is added along the body x axis ([`AeroCoeffs::from_lift_drag`], as the
//! built-in qualified model does).

use crate::aircraft::turboprop::{adx37, AircraftRef};
use crate::daveml::DaveModel;
use crate::delta_model::DeltaModel;
use crate::error::{AeroError, Result};
use crate::sim::aero::{AeroCoeffs, AeroInput, AeroModel};
use crate::sim::campaign::replay_states;
use crate::sim::extended::ExtendedAero;
use crate::sim::maneuver::Simulator;

/// A loop input a DAVE-ML variable can be bound to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Channel {
    AlphaDeg,
    AlphaRad,
    BetaDeg,
    BetaRad,
    Phat,
    Qhat,
    Rhat,
    AlphadotHat,
    AlphadotDps,
    BetadotDps,
    DaDeg,
    DeDeg,
    DeRad,
    DrDeg,
    DslDeg,
    DsrDeg,
    FlapDeg,
    CtLeft,
    CtRight,
    TasMps,
    Mach,
}

/// `varID` -> channel, the names [`DaveAero`] binds.
const CHANNELS: [(&str, Channel); 21] = [
    ("alpha_deg", Channel::AlphaDeg),
    ("alpha_rad", Channel::AlphaRad),
    ("beta_deg", Channel::BetaDeg),
    ("beta_rad", Channel::BetaRad),
    ("phat", Channel::Phat),
    ("qhat", Channel::Qhat),
    ("rhat", Channel::Rhat),
    ("alphadot_hat", Channel::AlphadotHat),
    ("alphadot_dps", Channel::AlphadotDps),
    ("betadot_dps", Channel::BetadotDps),
    ("da_deg", Channel::DaDeg),
    ("de_deg", Channel::DeDeg),
    ("de_rad", Channel::DeRad),
    ("dr_deg", Channel::DrDeg),
    ("dsl_deg", Channel::DslDeg),
    ("dsr_deg", Channel::DsrDeg),
    ("flap_deg", Channel::FlapDeg),
    ("ct_left", Channel::CtLeft),
    ("ct_right", Channel::CtRight),
    ("tas_mps", Channel::TasMps),
    ("mach", Channel::Mach),
];

/// How the model gives the longitudinal forces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Forces {
    /// Body-axis `CX`, `CZ` (indices), thrust included.
    Body(usize, usize),
    /// Lift and drag `CL`, `CD` (indices), thrust added along body x.
    LiftDrag(usize, usize),
}

/// A DAVE-ML model run by the simulator loop (see the module docs).
#[derive(Debug, Clone)]
pub struct DaveAero {
    model: DaveModel,
    inputs: Vec<(usize, Channel)>,
    forces: Forces,
    /// Indices of `CY`, `Cl`, `Cm`, `Cn`.
    moments: [usize; 4],
    /// Mean aerodynamic chord, m (for `alphadot_hat`).
    cbar_m: f64,
}

impl DaveAero {
    /// Bind `model`'s inputs and outputs; `cbar_m` (m) forms `alphadot_hat` when it is an input.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the file and what is missing: an output of `CY`,
    /// `Cl`, `Cm`, `Cn`, the force pair (`CX`, `CZ` or `CL`, `CD`), or an input without a
    /// default that is none of the bound channels.
    pub fn new(model: DaveModel, cbar_m: f64) -> Result<Self> {
        let out = |id: &str| model.outputs().iter().any(|v| v.id == id);
        let idx = |id: &str| model.index_of(id);
        let mut missing: Vec<String> = ["CY", "Cl", "Cm", "Cn"]
            .iter()
            .filter(|c| !out(c))
            .map(|c| (*c).to_string())
            .collect();
        let pick = |a: &str, b: &str| match (out(a), idx(a), out(b), idx(b)) {
            (true, Some(i), true, Some(j)) => Some((i, j)),
            _ => None,
        };
        let forces = if let Some((i, j)) = pick("CX", "CZ") {
            Some(Forces::Body(i, j))
        } else {
            pick("CL", "CD").map(|(i, j)| Forces::LiftDrag(i, j))
        };
        if forces.is_none() {
            missing.push("CX and CZ (or lift and drag, CL and CD)".into());
        }
        let mut unknown = Vec::new();
        let mut inputs = Vec::new();
        for v in model.inputs() {
            match CHANNELS.iter().find(|(id, _)| *id == v.id) {
                Some((_, ch)) => inputs.push((idx(&v.id).unwrap_or(usize::MAX), *ch)),
                None if v.initial_value.is_some() => {}
                None => unknown.push(v.id.clone()),
            }
        }
        let what = format!("DAVE-ML model {}", model.name());
        if !missing.is_empty() {
            return Err(AeroError::invalid(
                what,
                format!(
                    "the 6-DOF loop needs its outputs CY, Cl, Cm, Cn and the longitudinal forces; \
                     missing: {}",
                    missing.join(", ")
                ),
            ));
        }
        if !unknown.is_empty() {
            let known: Vec<&str> = CHANNELS.iter().map(|(id, _)| *id).collect();
            return Err(AeroError::invalid(
                what,
                format!(
                    "inputs {} are not channels the 6-DOF loop gives ({}); rename them or give \
                     them an initialValue",
                    unknown.join(", "),
                    known.join(", ")
                ),
            ));
        }
        if inputs.iter().any(|(i, _)| *i == usize::MAX) {
            return Err(AeroError::invalid(what, "an input has no variable index"));
        }
        let ix = |id: &str| idx(id).unwrap_or(usize::MAX);
        Ok(Self {
            forces: forces.unwrap_or(Forces::Body(usize::MAX, usize::MAX)),
            moments: [ix("CY"), ix("Cl"), ix("Cm"), ix("Cn")],
            model,
            inputs,
            cbar_m,
        })
    }

    fn value(&self, ch: Channel, inp: &AeroInput) -> f64 {
        let d = f64::to_degrees;
        let c = &inp.controls;
        match ch {
            Channel::AlphaDeg => d(inp.alpha),
            Channel::AlphaRad => inp.alpha,
            Channel::BetaDeg => d(inp.beta),
            Channel::BetaRad => inp.beta,
            Channel::Phat => inp.p_hat,
            Channel::Qhat => inp.q_hat,
            Channel::Rhat => inp.r_hat,
            Channel::AlphadotHat => inp.alpha_dot * self.cbar_m / (2.0 * inp.tas.max(1.0)),
            Channel::AlphadotDps => d(inp.alpha_dot),
            Channel::BetadotDps => d(inp.beta_dot),
            Channel::DaDeg => d(c.da),
            Channel::DeDeg => d(c.de),
            Channel::DeRad => c.de,
            Channel::DrDeg => d(c.dr),
            Channel::DslDeg => d(c.dsl),
            Channel::DsrDeg => d(c.dsr),
            Channel::FlapDeg => inp.flap_deg,
            Channel::CtLeft => inp.ct_left,
            Channel::CtRight => inp.ct_right,
            Channel::TasMps => inp.tas,
            Channel::Mach => inp.mach,
        }
    }
}

impl AeroModel for DaveAero {
    fn coefficients(&self, inp: &AeroInput) -> AeroCoeffs {
        let set: Vec<(usize, f64)> = self
            .inputs
            .iter()
            .map(|&(i, ch)| (i, self.value(ch, inp)))
            .collect();
        let mut values = vec![0.0; self.model.variables().len()];
        self.model.compute(&set, &mut values);
        let [cy, cl, cm, cn] = self.moments.map(|i| values[i]);
        let (cx, cz) = match self.forces {
            Forces::Body(i, j) => (values[i], values[j]),
            Forces::LiftDrag(i, j) => {
                AeroCoeffs::from_lift_drag(values[i], values[j], inp.alpha, inp.ct_sum())
            }
        };
        AeroCoeffs {
            cx,
            cy,
            cz,
            cl,
            cm,
            cn,
        }
    }
}

/// The reference values of a user's aircraft for [`replay_daveml`]: geometry (m, m²), mass
/// (kg), inertias (kg m², Etkin's I_xz), engines and propeller polar inertia (kg m²) and speed
/// (rpm, for the gyroscopic moment). The fields the replay does not read (engine geometry and
/// power, sensor positions: the campaign's pilot, engines and sensors) are the built-in
/// aircraft's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UserAircraft {
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
    /// Propeller polar inertia per propeller, kg m² (0: no gyroscopic moment).
    pub prop_inertia: f64,
    /// Propeller speed, rpm.
    pub prop_rpm: f64,
    /// CG position from the model's moment reference centre, body axes (x forward, y right,
    /// z down), m: the model's moments (about that centre, as DAVE-ML gives them) are
    /// transferred to the CG, `M_cg = M_ref − d × F` ([`Simulator::cg_offset`]).
    pub cg_offset_m: [f64; 3],
}

impl UserAircraft {
    /// The simulator's aircraft reference.
    ///
    /// # Errors
    /// A non-finite or non-positive geometry, mass or principal inertia.
    pub fn to_ref(&self) -> Result<AircraftRef> {
        for (name, v) in [
            ("S_m2", self.s_m2),
            ("b_m", self.b_m),
            ("cbar_m", self.cbar_m),
            ("mass_kg", self.mass_kg),
            ("Ixx_kgm2", self.ixx),
            ("Iyy_kgm2", self.iyy),
            ("Izz_kgm2", self.izz),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(AeroError::invalid(
                    format!("aircraft {name}"),
                    format!("{v} must be a positive number for the 6-DOF replay"),
                ));
            }
        }
        if !self.ixz.is_finite()
            || !self.prop_inertia.is_finite()
            || !self.prop_rpm.is_finite()
            || !self.cg_offset_m.iter().all(|v| v.is_finite())
        {
            return Err(AeroError::invalid(
                "aircraft Ixz_kgm2, prop_inertia_kgm2, prop_rpm, cg_m - moment_ref_m",
                "must be finite numbers for the 6-DOF replay",
            ));
        }
        Ok(AircraftRef {
            name: "user aircraft",
            s_m2: self.s_m2,
            b_m: self.b_m,
            cbar_m: self.cbar_m,
            mass_kg: self.mass_kg,
            ixx: self.ixx,
            iyy: self.iyy,
            izz: self.izz,
            ixz: self.ixz,
            n_engines: self.n_engines,
            prop_inertia: self.prop_inertia,
            prop_rpm: self.prop_rpm,
            ..adx37()
        })
    }
}

/// Replay recorded controls (da, de, dr, dsl, dsr in deg, Etkin) and thrust coefficients on
/// `aircraft` flown by the DAVE-ML `model`, plus the fitted Δ `delta` when given (thesis
/// Section 4.3, Eq. 3.12), from state `x0` with step `dt` (s). Returns the 12 states at each
/// step (n + 1 rows).
///
/// # Errors
/// A model the loop cannot bind ([`DaveAero::new`], [`ExtendedAero::new`]), a bad aircraft,
/// mismatched input lengths.
#[allow(clippy::too_many_arguments)]
pub fn replay_daveml(
    aircraft: &UserAircraft,
    model: &DaveModel,
    delta: Option<&DeltaModel>,
    flap_deg: f64,
    x0: [f64; 12],
    dt: f64,
    controls_deg: &[[f64; 5]],
    ct: &[[f64; 2]],
) -> Result<Vec<[f64; 12]>> {
    let ac = aircraft.to_ref()?;
    let base = DaveAero::new(model.clone(), ac.cbar_m)?;
    let mut sim = Simulator::new(ac, flap_deg, nalgebra::SVector::from(x0), dt);
    sim.cg_offset = nalgebra::Vector3::from(aircraft.cg_offset_m);
    match delta {
        Some(dm) => {
            let mut m = ExtendedAero::new(base, dm)?;
            replay_states(&mut sim, &mut m, controls_deg, ct)
        }
        None => {
            let mut m = base;
            replay_states(&mut sim, &mut m, controls_deg, ct)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dml(outputs: &[&str], extra_input: Option<&str>) -> DaveModel {
        let mut s = String::from(
            "<?xml version=\"1.0\"?><DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">\
             <fileHeader><author name=\"t\"/><creationDate date=\"2026-11-26\"/></fileHeader>\
             <variableDef name=\"alpha\" varID=\"alpha_deg\" units=\"deg\"><isInput/></variableDef>",
        );
        if let Some(x) = extra_input {
            s += &format!(
                "<variableDef name=\"{x}\" varID=\"{x}\" units=\"nd\"><isInput/></variableDef>"
            );
        }
        for (k, c) in outputs.iter().enumerate() {
            s += &format!(
                "<variableDef name=\"{c}\" varID=\"{c}\" units=\"nd\"><calculation><math>\
                 <apply><times/><ci>alpha_deg</ci><cn>{}</cn></apply></math></calculation>\
                 <isOutput/></variableDef>",
                k + 1
            );
        }
        s += "</DAVEfunc>";
        DaveModel::from_str(&s, "t.dml").expect("test model parses")
    }

    #[test]
    fn body_axis_outputs_pass_through() {
        let m = DaveAero::new(dml(&["CX", "CY", "CZ", "Cl", "Cm", "Cn"], None), 2.0).unwrap();
        let inp = AeroInput {
            alpha: 2f64.to_radians(),
            ct_left: 0.1,
            ..Default::default()
        };
        let c = m.coefficients(&inp);
        let a = 2.0;
        for (got, k) in [
            (c.cx, 1.0),
            (c.cy, 2.0),
            (c.cz, 3.0),
            (c.cl, 4.0),
            (c.cm, 5.0),
            (c.cn, 6.0),
        ] {
            assert!((got - k * a).abs() < 1e-12, "{got} {k}");
        }
    }

    #[test]
    fn lift_drag_rotate_and_take_thrust() {
        let m = DaveAero::new(dml(&["CL", "CD", "CY", "Cl", "Cm", "Cn"], None), 2.0).unwrap();
        let alpha = 10f64.to_radians();
        let inp = AeroInput {
            alpha,
            ct_left: 0.05,
            ct_right: 0.02,
            ..Default::default()
        };
        let c = m.coefficients(&inp);
        let (lift, drag) = (10.0, 20.0);
        let cx = -drag * alpha.cos() + lift * alpha.sin() + 0.07;
        let cz = -drag * alpha.sin() - lift * alpha.cos();
        assert!((c.cx - cx).abs() < 1e-12 && (c.cz - cz).abs() < 1e-12);
    }

    #[test]
    fn missing_outputs_and_unknown_inputs_are_named() {
        let e = DaveAero::new(dml(&["CY", "Cl", "Cn"], None), 2.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("missing: Cm, CX and CZ (or lift and drag, CL and CD)"),
            "{e}"
        );
        let e = DaveAero::new(
            dml(&["CX", "CY", "CZ", "Cl", "Cm", "Cn"], Some("wind_kt")),
            2.0,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("inputs wind_kt are not channels"), "{e}");
    }
}
