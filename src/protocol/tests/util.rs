//! Host test rig for the protocol: the ISR end and the loader end on one thread, a small
//! settings table ($10, $13 and a free map), and the real G-code parser answering lines.

extern crate std;
use super::super::*;
use crate::gcode::Parser;
use std::boxed::Box;
use std::collections::BTreeMap;
use std::string::{String, ToString};
use std::vec::Vec;

/// A settings table with `$10`, `$13` and any other number stored as given.
#[derive(Default)]
pub struct Table {
    pub mask: u8,
    pub inches: bool,
    pub other: BTreeMap<u16, Decimal>,
}

impl SettingsTable for Table {
    fn list(&self, out: &mut dyn Write) -> fmt::Result {
        write!(out, "$10={}\r\n$13={}\r\n", self.mask, self.inches as u8)?;
        for (n, v) in &self.other {
            write!(out, "${n}={v}\r\n")?;
        }
        Ok(())
    }
    fn set(&mut self, n: u16, value: Decimal) -> Result<(), u8> {
        let int = || value.as_integer().ok_or(2u8);
        match n {
            10 => self.mask = u8::try_from(int()?).map_err(|_| 3u8)?,
            13 => self.inches = int()? != 0,
            100..=199 => {
                self.other.insert(n, value);
            }
            _ => return Err(3),
        }
        Ok(())
    }
    fn report_options(&self) -> ReportOptions {
        ReportOptions {
            status_mask: self.mask,
            inches: self.inches,
        }
    }
}

/// An owned [`Event`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Ev {
    Gcode(String, bool),
    Jog(JogRequest),
    Home(u8),
    Realtime(Pending),
    Reset,
    Replied,
    Unlock,
    CheckMode(bool),
    Overflow(u32),
}

pub struct Rig {
    pub isr: RxIsr<'static>,
    pub p: Protocol<'static>,
    pub out: String,
    pub table: Table,
    pub machine: Settings,
    pub parser: Parser,
    pub state: State,
    pub line_no: u32,
    /// What the loader passes as [`Context::frame_cycles`].
    pub frame_cycles: Option<(u32, u32)>,
    /// What the loader passes as [`Context::interlock`].
    pub interlock: Option<u8>,
}

impl Rig {
    pub fn new() -> Rig {
        let shared: &'static mut RxShared = Box::leak(Box::new(RxShared::new()));
        let (isr, task) = shared.split();
        let machine = Settings::default();
        Rig {
            isr,
            p: Protocol::new(task, 15),
            out: String::new(),
            table: Table {
                mask: 1,
                ..Table::default()
            },
            machine,
            parser: Parser::new(machine),
            state: State::Idle,
            line_no: 0,
            frame_cycles: None,
            interlock: None,
        }
    }

    /// Pushes bytes from the "ISR".
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Push> {
        bytes.iter().map(|&b| self.isr.push_byte(b)).collect()
    }

    /// One poll; a G-code line is parsed by the real parser and answered, a jog planned and
    /// answered.
    pub fn poll(&mut self) -> Option<Ev> {
        let mut cx = Context {
            table: &mut self.table,
            modes: self.parser.modes(),
            offsets: crate::protocol::report::OffsetsReport {
                offsets: *self.parser.offsets(),
                tlo_pm: self.parser.modes().tlo_pm,
                probe: ([0; 3], false),
            },
            machine: &self.machine,
            state: self.state,
            frame_cycles: self.frame_cycles,
            interlock: self.interlock,
        };
        let ev = match self.p.poll(&mut self.out, &mut cx) {
            Event::None => return None,
            Event::Replied => Ev::Replied,
            Event::Gcode { line, check } => Ev::Gcode(line.to_string(), check),
            Event::Jog(j) => Ev::Jog(j),
            Event::Home(m) => Ev::Home(m),
            Event::Realtime(p) => Ev::Realtime(p),
            Event::Reset => Ev::Reset,
            Event::Unlock => Ev::Unlock,
            Event::CheckMode(c) => Ev::CheckMode(c),
            Event::RxOverflow { lost } => Ev::Overflow(lost),
            Event::End => unreachable!("the protocol's lines do not end"),
        };
        match &ev {
            Ev::Gcode(line, _) => {
                self.line_no += 1;
                let r = match self.parser.line(self.line_no, line) {
                    Ok(_) => Ok(()),
                    Err(e) => Err(GrblError::from(e)),
                };
                assert!(self.p.reply(r, &mut self.out));
            }
            Ev::Jog(j) => {
                let r = j.plan(&self.parser).map(|_| ());
                assert!(self.p.reply(r, &mut self.out));
            }
            // The loader's homing cycle, done at once.
            Ev::Home(_) => assert!(self.p.reply(Ok(()), &mut self.out)),
            Ev::Reset => self.parser = Parser::new(self.machine),
            _ => {}
        }
        Some(ev)
    }

    /// Polls until nothing is left; the events.
    pub fn run(&mut self) -> Vec<Ev> {
        let mut v = Vec::new();
        while let Some(e) = self.poll() {
            v.push(e);
        }
        v
    }

    /// Sends `bytes`, polling whenever the ring is full (a sender that never overfills).
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<Ev> {
        let mut v = Vec::new();
        for &b in bytes {
            if self.p.rx_available() == 0 && !rx::byte::is_realtime(b) {
                v.extend(self.run());
            }
            assert_ne!(self.isr.push_byte(b), Push::Refused);
        }
        v.extend(self.run());
        v
    }

    /// The output so far, taken.
    pub fn take(&mut self) -> String {
        core::mem::take(&mut self.out)
    }

    /// The `ok` / `error:N` responses in the output, taken (other lines dropped).
    pub fn responses(&mut self) -> Vec<String> {
        self.take()
            .split("\r\n")
            .filter(|l| *l == "ok" || l.starts_with("error:"))
            .map(|l| l.to_string())
            .collect()
    }
}
