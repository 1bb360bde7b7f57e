//! The feed drives (host): how the tool follows the commanded position (the step pulses counted so
//! far). A stepper follows them exactly; a servo drive follows through its position loop, which
//! the HOAM-CNC thesis (Munasinghe 1994, appendix B, Eq. B.6) approximates per axis by the
//! underdamped second-order system
//!
//! `G(s) = wn^2 / (s^2 + 2 zeta wn s + wn^2)`, wn^2 = 60317.78 s^-2, 2 zeta wn = 400 s^-1
//!
//! (wn = 245.6 rad/s, zeta = 0.814: about 1.2 % overshoot, and a following lag of 2 zeta / wn =
//! 6.63 ms times the feed). The process then cuts where the tool really is, so an adaptive
//! controller sees the drive's lag, as it did on the thesis' machine and on the HP's.
//!
//! Integration: the commanded position is held over each call's interval (zero-order hold, as the
//! pulses reach the drive) and the loop is integrated with fourth-order Runge-Kutta in steps of
//! at most [`MAX_STEP_S`] (wn h <= 0.025): deterministic, only + and *. Called once per ADC
//! sample by the process's driver (cosim bridge, host simulation).

/// The longest integration step, s.
pub const MAX_STEP_S: f64 = 1.0e-4;

/// A feed drive model, per run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriveModel {
    /// The tool is where the pulses put it.
    Stepper,
    /// A second-order position loop per axis: wn^2 (s^-2) and 2 zeta wn (s^-1).
    Servo { wn2: f64, two_zeta_wn: f64 },
}

impl DriveModel {
    /// The thesis' feed drive (appendix B, Eq. B.6).
    pub const THESIS: DriveModel = DriveModel::Servo {
        wn2: 60_317.778_4,
        two_zeta_wn: 400.0,
    };
}

/// The three axes' drive state: position (BLU, fractional) and velocity (BLU/s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    model: DriveModel,
    pos: [f64; 3],
    vel: [f64; 3],
    t_s: f64,
}

impl Drive {
    /// A drive at rest at `start` (BLU).
    pub fn new(model: DriveModel, start: [i64; 3]) -> Self {
        Drive {
            model,
            pos: start.map(|p| p as f64),
            vel: [0.0; 3],
            t_s: 0.0,
        }
    }

    /// The tool position (BLU) at time `t_s` with the command `cmd` (BLU) held since the last
    /// call. A stepper returns the command itself.
    pub fn follow(&mut self, t_s: f64, cmd: [i64; 3]) -> [f64; 3] {
        let target = cmd.map(|c| c as f64);
        match self.model {
            DriveModel::Stepper => {
                self.pos = target;
                self.vel = [0.0; 3];
            }
            DriveModel::Servo { wn2, two_zeta_wn } => {
                let span = t_s - self.t_s;
                if span > 0.0 {
                    let steps = (span / MAX_STEP_S).ceil().max(1.0);
                    let h = span / steps;
                    for _ in 0..steps as u64 {
                        for ((x, v), c) in self.pos.iter_mut().zip(&mut self.vel).zip(&target) {
                            (*x, *v) = rk4(*x, *v, *c, h, wn2, two_zeta_wn);
                        }
                    }
                }
            }
        }
        self.t_s = t_s;
        self.pos
    }
}

/// One RK4 step of x'' = wn2 (c - x) - 2 zeta wn x'.
fn rk4(x: f64, v: f64, c: f64, h: f64, wn2: f64, d: f64) -> (f64, f64) {
    let acc = |x: f64, v: f64| wn2 * (c - x) - d * v;
    let (k1x, k1v) = (v, acc(x, v));
    let (k2x, k2v) = (v + 0.5 * h * k1v, acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v));
    let (k3x, k3v) = (v + 0.5 * h * k2v, acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v));
    let (k4x, k4v) = (v + h * k3v, acc(x + h * k3x, v + h * k3v));
    (
        x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
        v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// zeta and wn of the thesis' loop.
    fn zeta_wn() -> (f64, f64) {
        let wn = 60_317.778_4f64.sqrt();
        (400.0 / (2.0 * wn), wn)
    }

    #[test]
    fn a_stepper_is_where_the_pulses_put_it() {
        let mut d = Drive::new(DriveModel::Stepper, [5, -3, 0]);
        assert_eq!(d.follow(0.001, [7, -3, 2]), [7.0, -3.0, 2.0]);
    }

    /// A step of 1000 BLU: the overshoot and the time of the peak are the second-order system's,
    /// exp(-pi zeta / sqrt(1 - zeta^2)) and pi / (wn sqrt(1 - zeta^2)).
    #[test]
    fn a_servo_step_overshoots_as_its_second_order_model() {
        let (zeta, wn) = zeta_wn();
        let wd = wn * (1.0 - zeta * zeta).sqrt();
        let want_os = (-std::f64::consts::PI * zeta / (1.0 - zeta * zeta).sqrt()).exp();
        let want_tp = std::f64::consts::PI / wd;
        let mut d = Drive::new(DriveModel::THESIS, [0, 0, 0]);
        let (mut peak, mut t_peak) = (0.0f64, 0.0f64);
        for k in 1..=100_000 {
            let t = k as f64 * 1.0e-5;
            let x = d.follow(t, [1000, 0, 0])[0];
            if x > peak {
                peak = x;
                t_peak = t;
            }
        }
        let os = peak / 1000.0 - 1.0;
        assert!((os - want_os).abs() < 1.0e-4, "overshoot {os} vs {want_os}");
        assert!(
            (t_peak - want_tp).abs() < 2.0e-5,
            "peak at {t_peak} vs {want_tp}"
        );
    }

    /// A ramp at v: after the transient the tool trails the command by 2 zeta / wn x v (6.63 ms of
    /// travel), the same whatever the sample interval.
    #[test]
    fn a_servo_trails_a_ramp_by_two_zeta_over_wn() {
        let v = 10_000.0; // BLU/s (about 60 ipm)
        let want = 400.0 / 60_317.778_4 * v;
        for dt in [1.0e-3, 2.5e-4] {
            let mut d = Drive::new(DriveModel::THESIS, [0, 0, 0]);
            let mut lag = 0.0;
            let n = (0.5 / dt) as u64;
            for k in 1..=n {
                let t = k as f64 * dt;
                let cmd = (v * t).round() as i64;
                lag = cmd as f64 - d.follow(t, [cmd, 0, 0])[0];
            }
            // Each command is the ramp's value at the END of its interval, held over it: on
            // average the drive sees the ramp half an interval early, and trails the command at
            // the end of the interval by half an interval of travel less.
            let held = 0.5 * v * dt;
            assert!(
                (lag - (want - held)).abs() < 0.01 * want,
                "dt {dt}: lag {lag} vs {want} - {held}"
            );
        }
    }
}
