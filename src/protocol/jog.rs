//! `$J=` jog commands (loader task, host tests): parsed into a [`JogRequest`] with grbl's rules
//! (one or more of X Y Z, F required and not modal, only G20/G21/G90/G91 allowed and only for this
//! command, N ignored), then validated like any block by running an equivalent `G1` line on a
//! copy of the parser, so the jog changes no modal state.

use super::codes::GrblError;
use crate::gcode::words::{self, Words};
use crate::gcode::{Decimal, Distance, ErrorKind, Parser, Units};
use crate::nc::Block;
use core::fmt::{self, Write};

/// A parsed `$J=` line. Units and distance mode are the parser's unless given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JogRequest {
    /// X, Y, Z targets (absolute or increments), in the jog's units.
    pub target: [Option<Decimal>; 3],
    /// Feed in the jog's units per minute; always given, greater than zero.
    pub feed: Decimal,
    /// G20 / G21 on the jog line.
    pub units: Option<Units>,
    /// G90 / G91 on the jog line.
    pub distance: Option<Distance>,
    /// G53 on the jog line: the targets are machine coordinates (else the work coordinates in
    /// force, as any program line).
    pub machine: bool,
}

/// A validated jog: the block to queue (after `gcode::tape::finish_block`, like every block) and
/// the machine position where it ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JogPlan {
    /// `None` when the jog ends where it starts.
    pub block: Option<Block>,
    pub end: [i32; 3],
}

impl JogRequest {
    /// Parses the text after `$J=` (any case, spaces and comments allowed).
    pub fn parse(text: &str) -> Result<JogRequest, GrblError> {
        let w: Words = words::lex(text).map_err(|e| GrblError::from(&e))?;
        let machine = w.g[words::G_NON_MODAL] == Some(530);
        let allowed = |group: usize, g: u16| {
            group == words::G_UNITS
                || group == words::G_DISTANCE
                || (group == words::G_NON_MODAL && g == 530)
        };
        let other_g =
            w.g.iter()
                .enumerate()
                .any(|(group, g)| g.is_some_and(|g| !allowed(group, g)));
        if other_g || w.m.iter().any(Option::is_some) {
            return Err(GrblError::INVALID_JOG);
        }
        for (i, v) in w.values.iter().enumerate() {
            let jog_word = i == words::F
                || words::LETTERS.get(i) == Some(&'N')
                || (words::AXES..words::AXES + 3).contains(&i);
            if v.is_some() && !jog_word {
                return Err(GrblError::UNUSED_WORDS);
            }
        }
        let feed = w.value(words::F).ok_or(GrblError::UNDEFINED_FEED)?;
        if feed.is_negative() {
            return Err(GrblError::NEGATIVE_VALUE);
        }
        if feed.is_zero() {
            return Err(GrblError::UNDEFINED_FEED);
        }
        let target = [0, 1, 2].map(|k| w.value(words::AXES + k));
        if target.iter().all(Option::is_none) {
            return Err(GrblError::NO_AXIS_WORDS);
        }
        let units = w.g[words::G_UNITS].map(|g| if g == 200 { Units::Inch } else { Units::Mm });
        let distance = w.g[words::G_DISTANCE].map(|g| {
            if g == 910 {
                Distance::Incremental
            } else {
                Distance::Absolute
            }
        });
        Ok(JogRequest {
            target,
            feed,
            units,
            distance,
            machine,
        })
    }

    /// The equivalent G-code line, e.g. `G1 G91 G21 X1 F100` (G53 when the jog has it); the
    /// session log writes the words after `G1` as the jog's `$J=` words.
    pub fn write_gcode(&self, out: &mut dyn Write) -> fmt::Result {
        out.write_str("G1")?;
        if self.machine {
            out.write_str(" G53")?;
        }
        match self.distance {
            Some(Distance::Incremental) => out.write_str(" G91")?,
            Some(Distance::Absolute) => out.write_str(" G90")?,
            None => {}
        }
        match self.units {
            Some(Units::Inch) => out.write_str(" G20")?,
            Some(Units::Mm) => out.write_str(" G21")?,
            None => {}
        }
        for (k, v) in self.target.iter().enumerate() {
            if let Some(v) = v {
                write!(out, " {}{}", ['X', 'Y', 'Z'][k], v)?;
            }
        }
        write!(out, " F{}", self.feed)
    }

    /// Validates the jog like any block against the parser's state (position, modes, soft limits)
    /// without changing it. A jog past the soft limits is `error:15`, as in grbl.
    pub fn plan(&self, parser: &Parser) -> Result<JogPlan, GrblError> {
        let mut line: heapless::String<256> = heapless::String::new();
        // Four numbers of at most 40 characters and seven codes fit in 256 bytes. G94: a jog's F
        // is a feed per minute whatever the program's feed mode.
        line.push_str("G94 ").map_err(|_| GrblError::OVERFLOW)?;
        self.write_gcode(&mut line)
            .map_err(|_| GrblError::OVERFLOW)?;
        match parser.plan_aside(&line, false) {
            Ok((block, end, _)) => Ok(JogPlan { block, end }),
            Err(e) => Err(match e.kind {
                ErrorKind::SoftLimit { .. } => GrblError::TRAVEL_EXCEEDED,
                k => GrblError::from(&k),
            }),
        }
    }
}
