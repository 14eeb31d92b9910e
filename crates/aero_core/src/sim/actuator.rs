//! Control-surface actuators: a first-order lag with a rate limit and
//! position limits, advanced once per fixed step.

/// One actuator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuator {
    /// Time constant, s.
    pub time_constant_s: f64,
    /// Rate limit, rad/s.
    pub rate_limit: f64,
    /// Lower position limit, rad.
    pub min: f64,
    /// Upper position limit, rad.
    pub max: f64,
    /// Current position, rad.
    pub position: f64,
}

impl Actuator {
    /// An actuator at rest at `position` (clamped to its limits).
    pub fn new(time_constant_s: f64, rate_limit: f64, min: f64, max: f64, position: f64) -> Self {
        Actuator {
            time_constant_s,
            rate_limit,
            min,
            max,
            position: position.clamp(min, max),
        }
    }

    /// Move towards `command` for `dt` s: rate = clamp((cmd − x)/τ, ±rate limit).
    pub fn advance(&mut self, command: f64, dt: f64) -> f64 {
        let cmd = command.clamp(self.min, self.max);
        let tau = self.time_constant_s.max(dt);
        let rate = ((cmd - self.position) / tau).clamp(-self.rate_limit, self.rate_limit);
        let next = self.position + rate * dt;
        // never overshoot the command
        self.position = if (cmd - self.position) * (cmd - next) < 0.0 {
            cmd
        } else {
            next
        };
        self.position
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rate_limit_and_position_limit_hold() {
        let mut a = Actuator::new(0.05, 1.0, -0.3, 0.3, 0.0);
        a.advance(1.0, 0.01);
        assert!((a.position - 0.01).abs() < 1e-12, "rate limited to 1 rad/s");
        for _ in 0..1000 {
            a.advance(1.0, 0.01);
        }
        assert!((a.position - 0.3).abs() < 1e-12);
    }

    #[test]
    fn small_steps_follow_first_order_lag() {
        let mut a = Actuator::new(0.1, 100.0, -1.0, 1.0, 0.0);
        for _ in 0..10000 {
            a.advance(0.01, 1e-5);
        }
        // after 0.1 s = one time constant: 1 - e^-1 of the step
        assert!((a.position / 0.01 - (1.0 - (-1.0f64).exp())).abs() < 1e-3);
    }
}
