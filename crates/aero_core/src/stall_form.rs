//! The identified longitudinal stall in either form of its static separation
//! curve: Fischenberg's tanh `x₀(α) = ½(1 − tanh(a₁(α − α*)))`
//! ([`crate::kirchhoff`]; AIAA 95-3438, 1995) or Goman & Khrabrov's tabulated
//! `x₀(α)` ([`crate::goman_khrabrov`]; J. Aircraft 31(5), 1994), over the same
//! separation dynamics `τ₁ ẋ + x = x₀(α − τ₂ α̇)`, Kirchhoff lift and pitch
//! break.
//!
//! A simulator that loads a Δ model flies whichever form the model stores
//! ([`crate::stall_spec`]): [`crate::aircraft::truth::KirchhoffStall`] steps a
//! [`StallState`] over these parameters.

use crate::error::Result;
use crate::goman_khrabrov::GkParams;
use crate::kirchhoff::{KirchhoffParams, Separation, SeparationState};

/// The parameters of one flap's stall, in the form it was identified in.
#[derive(Debug, Clone, PartialEq)]
pub enum StallParams {
    /// The tanh separation curve (Fischenberg).
    Kirchhoff(KirchhoffParams),
    /// The tabulated separation curve (Goman-Khrabrov).
    GomanKhrabrov(GkParams),
}

impl From<KirchhoffParams> for StallParams {
    fn from(p: KirchhoffParams) -> Self {
        StallParams::Kirchhoff(p)
    }
}

impl From<GkParams> for StallParams {
    fn from(p: GkParams) -> Self {
        StallParams::GomanKhrabrov(p)
    }
}

impl StallParams {
    /// The form's name in a model file: `kirchhoff` or `goman-khrabrov`.
    pub fn form(&self) -> &'static str {
        match self {
            StallParams::Kirchhoff(_) => "kirchhoff",
            StallParams::GomanKhrabrov(_) => "goman-khrabrov",
        }
    }

    /// The static separation point `x₀(α)`, α in rad.
    #[inline]
    pub fn x0(&self, alpha: f64) -> f64 {
        match self {
            StallParams::Kirchhoff(p) => p.x0(alpha),
            StallParams::GomanKhrabrov(p) => p.x0.eval(alpha),
        }
    }

    /// Lift coefficient (static-curve part) at α (rad) and separation point `x`.
    #[inline]
    pub fn cl(&self, alpha: f64, x: f64) -> f64 {
        match self {
            StallParams::Kirchhoff(p) => p.cl(alpha, x),
            StallParams::GomanKhrabrov(p) => p.cl(alpha, x),
        }
    }

    /// Pitching moment coefficient (static-curve part) at α (rad) and `x`.
    #[inline]
    pub fn cm(&self, alpha: f64, x: f64) -> f64 {
        match self {
            StallParams::Kirchhoff(p) => p.cm(alpha, x),
            StallParams::GomanKhrabrov(p) => p.cm(alpha, x),
        }
    }

    /// The ODE's right-hand side `ẋ = (x₀(α − τ₂ α̇) − x) / τ₁`, 1/s (what a host
    /// integrating the state itself evaluates).
    #[inline]
    pub fn x_dot(&self, alpha: f64, alpha_dot: f64, x: f64) -> f64 {
        (self.x0_lagged(alpha, alpha_dot) - x) / self.tau1()
    }

    /// The convective lag τ₂, s.
    pub fn tau2(&self) -> f64 {
        match self {
            StallParams::Kirchhoff(p) => p.tau2,
            StallParams::GomanKhrabrov(p) => p.tau2,
        }
    }

    /// The maximum of the static lift curve: `(α at C_L,max [rad], C_L,max)`
    /// ([`KirchhoffParams::cl_max`], [`GkParams::cl_max`]).
    pub fn cl_max(&self) -> (f64, f64) {
        match self {
            StallParams::Kirchhoff(p) => p.cl_max(),
            StallParams::GomanKhrabrov(p) => p.cl_max(),
        }
    }
}

impl Separation for StallParams {
    #[inline]
    fn x0_lagged(&self, alpha: f64, alpha_dot: f64) -> f64 {
        match self {
            StallParams::Kirchhoff(p) => p.x0_lagged(alpha, alpha_dot),
            StallParams::GomanKhrabrov(p) => p.x0_lagged(alpha, alpha_dot),
        }
    }
    #[inline]
    fn tau1(&self) -> f64 {
        match self {
            StallParams::Kirchhoff(p) => p.tau1,
            StallParams::GomanKhrabrov(p) => p.tau1,
        }
    }
    fn check_params(&self) -> Result<()> {
        match self {
            StallParams::Kirchhoff(p) => p.check(),
            StallParams::GomanKhrabrov(p) => p.check(),
        }
    }
}

/// The running separation state of a stall in either form.
pub type StallState = SeparationState<StallParams>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::goman_khrabrov::X0Table;
    use crate::kirchhoff::tests::truth;
    use crate::kirchhoff::KirchhoffState;

    /// A table that samples the tanh truth's curve at 1 deg.
    fn table_form() -> GkParams {
        let p = truth();
        let knots: Vec<f64> = (0..30).map(|k| (2.0 + k as f64).to_radians()).collect();
        let values = knots.iter().map(|&a| p.x0(a)).collect();
        GkParams::with_table(&p, X0Table::new(knots, values).expect("table"))
    }

    #[test]
    fn each_form_steps_as_its_own_state() {
        // the enum's state equals each form's own state step for step (the same arithmetic)
        let (pk, pg) = (truth(), table_form());
        let mut own_k = KirchhoffState::new(pk).expect("tanh");
        let mut own_g = crate::goman_khrabrov::GkState::new(pg.clone()).expect("table");
        let mut any_k = StallState::new(pk.into()).expect("tanh");
        let mut any_g = StallState::new(pg.clone().into()).expect("table");
        for k in 0..400 {
            let t = k as f64 * 0.01;
            let a = (8.0 + 14.0 * (0.9 * t).sin()).to_radians();
            let ad = (14.0 * 0.9 * (0.9 * t).cos()).to_radians();
            own_k.update(t, a, ad);
            own_g.update(t, a, ad);
            any_k.update(t, a, ad);
            any_g.update(t, a, ad);
            assert_eq!(any_k.x_at(a, ad), own_k.x_at(a, ad));
            assert_eq!(any_g.x_at(a, ad), own_g.x_at(a, ad));
            let x = any_g.x_at(a, ad);
            assert_eq!(any_g.params.cl(a, x), pg.cl(a, x));
            assert_eq!(any_g.params.cm(a, x), pg.cm(a, x));
            assert_eq!(any_k.params.cl(a, x), pk.cl(a, x));
        }
        assert_eq!(any_g.params.form(), "goman-khrabrov");
        assert_eq!(any_k.params.form(), "kirchhoff");
        assert_eq!(any_k.params.tau2(), pk.tau2);
        assert_eq!(StallParams::from(pg.clone()).cl_max(), pg.cl_max());
    }

    #[test]
    fn a_bad_table_is_refused_by_the_state() {
        let mut p = table_form();
        p.tau1 = -0.1;
        let e = StallState::new(p.into()).unwrap_err().to_string();
        assert!(e.contains("tau1"), "{e}");
    }
}
