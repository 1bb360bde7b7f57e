//! The Nucleo-F446RE as the loader sees it (idle loader; the AC task's log): USART2 (started,
//! kicked), the operator inputs through the shared debouncer (a short lock against the sampler),
//! the spindle outputs, the frame's cycle limit, and the AC log at defmt's debug level.
use millac::gcode::Spindle;
use millac::inputs::{Debouncer, Events, Trip};
use millac::rt::actask::LogSink;
use millac::rt::loader::LoaderBoard;
use rtic::Mutex;
use stm32f4xx_hal::gpio::{AnyPin, Output};

use crate::board;
use crate::facts::F446;

/// Pends USART2 so that it moves queued bytes out (the serial console's writer).
pub fn kick() {
    rtic::pend(stm32f4xx_hal::pac::Interrupt::USART2);
}

/// The board as the serial loader sees it: USART2, the operator inputs (through the shared
/// debouncer: a short lock against the sampler), the spindle outputs.
pub struct Nucleo<'a, M: Mutex<T = Debouncer>> {
    pub inputs: M,
    pub enable: &'a mut AnyPin<Output>,
    pub direction: &'a mut AnyPin<Output>,
    /// The frame work the running settings tolerate, in DWT cycles.
    pub frame_limit: u32,
}

impl<M: Mutex<T = Debouncer>> LoaderBoard for Nucleo<'_, M> {
    fn start(&mut self) {
        board::usart2_start();
    }

    type Board = F446;

    /// Enable high for M3/M4, direction high for M4, PWM duty S / `$30`.
    fn spindle(&mut self, state: Spindle, rpm: u32, max_rpm: u32) {
        match state {
            Spindle::Off => {
                board::spindle_pwm_set(0);
                self.enable.set_low();
            }
            Spindle::Cw | Spindle::Ccw => {
                self.direction.set_state((state == Spindle::Ccw).into());
                board::spindle_pwm_set(board::spindle_duty(rpm, max_rpm));
                self.enable.set_high();
            }
        }
        defmt::info!("spindle {} at {} rpm", defmt::Debug2Format(&state), rpm);
    }

    fn frame_limit_cycles(&self) -> Option<u32> {
        Some(self.frame_limit)
    }

    fn inputs(&mut self) -> Events {
        self.inputs.lock(|d| d.take())
    }

    fn latched(&mut self) -> Option<Trip> {
        self.inputs.lock(|d| d.latched())
    }

    fn acknowledge(&mut self) -> bool {
        self.inputs.lock(|d| d.acknowledge())
    }

    fn latch_active(&mut self) -> bool {
        self.inputs.lock(|d| {
            let i = d.inputs();
            d.latched().is_some() && (i.estop || i.limits != 0)
        })
    }
}

/// The AC log lines at defmt's debug level (`DEFMT_LOG=debug` to see them).
pub struct DefmtLog;

impl LogSink for DefmtLog {
    fn write(&mut self, bytes: &[u8]) {
        if let Ok(s) = core::str::from_utf8(bytes) {
            defmt::debug!("{=str}", s.trim_end());
        }
    }
}
