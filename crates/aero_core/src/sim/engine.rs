//! A simple turboprop engine and constant-speed propeller: power lever →
//! shaft power (first-order spool lag) → thrust T = η P / V, capped by a
//! static-thrust limit at low speed; C_T = T/(q̄ S) per engine (the thesis's
//! thrust coefficient, Table 3.1 and Eq. 3.17).

/// Engine and propeller constants (one engine).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EngineSpec {
    /// Maximum shaft power at sea level, W.
    pub max_power_w: f64,
    /// Flight-idle shaft power at sea level, W.
    pub idle_power_w: f64,
    /// Power response time constant, s.
    pub time_constant_s: f64,
    /// Propeller efficiency η (constant-speed prop in climb), -.
    pub efficiency: f64,
    /// Static-thrust limit, N.
    pub max_thrust_n: f64,
    /// Governed propeller speed, rpm.
    pub prop_rpm: f64,
    /// Exponent of the density lapse of available power, P ∝ σ^k.
    pub density_exponent: f64,
}

/// The state of one engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Engine {
    /// Constants.
    pub spec: EngineSpec,
    /// Current shaft power, W.
    pub power_w: f64,
}

impl Engine {
    /// An engine already settled at the power of lever position `lever` (0 idle … 1 max).
    pub fn settled(spec: EngineSpec, lever: f64, sigma: f64) -> Self {
        let mut e = Engine { spec, power_w: 0.0 };
        e.power_w = e.commanded_power(lever, sigma);
        e
    }

    /// Shaft power commanded by the lever at density ratio `sigma`, W.
    pub fn commanded_power(&self, lever: f64, sigma: f64) -> f64 {
        let lapse = sigma.max(0.0).powf(self.spec.density_exponent);
        let l = lever.clamp(0.0, 1.0);
        lapse * (self.spec.idle_power_w + l * (self.spec.max_power_w - self.spec.idle_power_w))
    }

    /// Lever position that commands shaft power `power_w` at density ratio `sigma` (unclamped).
    pub fn lever_for_power(&self, power_w: f64, sigma: f64) -> f64 {
        let lapse = sigma.max(1e-6).powf(self.spec.density_exponent);
        (power_w / lapse - self.spec.idle_power_w)
            / (self.spec.max_power_w - self.spec.idle_power_w)
    }

    /// Advance the spool lag by `dt` s (exact first-order response).
    pub fn advance(&mut self, lever: f64, sigma: f64, dt: f64) {
        let target = self.commanded_power(lever, sigma);
        let a = (-dt / self.spec.time_constant_s).exp();
        self.power_w = target + (self.power_w - target) * a;
    }

    /// Thrust at true airspeed `tas` (m/s), N.
    pub fn thrust(&self, tas: f64) -> f64 {
        (self.spec.efficiency * self.power_w / tas.max(1.0)).min(self.spec.max_thrust_n)
    }

    /// Shaft power that gives thrust `thrust_n` at `tas` (inverse of [`Engine::thrust`]), W.
    pub fn power_for_thrust(&self, thrust_n: f64, tas: f64) -> f64 {
        thrust_n * tas.max(1.0) / self.spec.efficiency
    }

    /// Propeller angular speed, rad/s.
    pub fn prop_omega(&self) -> f64 {
        self.spec.prop_rpm * std::f64::consts::PI / 30.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> EngineSpec {
        EngineSpec {
            max_power_w: 1.49e6,
            idle_power_w: 0.06e6,
            time_constant_s: 1.0,
            efficiency: 0.8,
            max_thrust_n: 30_000.0,
            prop_rpm: 1020.0,
            density_exponent: 0.7,
        }
    }

    #[test]
    fn thrust_is_power_over_speed_with_a_static_limit() {
        let e = Engine::settled(spec(), 1.0, 1.0);
        assert!((e.thrust(100.0) - 0.8 * 1.49e6 / 100.0).abs() < 1e-6);
        assert_eq!(e.thrust(5.0), 30_000.0);
        let p = e.power_for_thrust(5000.0, 70.0);
        let e2 = Engine { power_w: p, ..e };
        assert!((e2.thrust(70.0) - 5000.0).abs() < 1e-9);
        assert!((e.lever_for_power(e.commanded_power(0.37, 0.8), 0.8) - 0.37).abs() < 1e-12);
    }

    #[test]
    fn spool_lag_is_first_order() {
        let mut e = Engine::settled(spec(), 0.0, 1.0);
        let p0 = e.power_w;
        let target = e.commanded_power(1.0, 1.0);
        for _ in 0..100 {
            e.advance(1.0, 1.0, 0.01);
        }
        // after one time constant: 63.2 % of the step
        let frac = (e.power_w - p0) / (target - p0);
        assert!((frac - (1.0 - (-1.0f64).exp())).abs() < 1e-9);
    }
}
