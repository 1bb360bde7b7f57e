//! A frame driven without hardware: feeds blocks to [`Frame::tick`] and yields every frame's output
//! with the rate it ran at. Used by host tests and the host tool (host); never by the firmware.
use super::block::Sealed;
use super::frame::{Frame, Pulses, Rate};
use crate::ports::BlockSource;

/// One simulated frame: its index, the rate the frame timer ran at for it, and its output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimFrame {
    pub tick: u64,
    pub rate: Rate,
    pub pulses: Pulses,
    /// Position after the frame.
    pub position: [i32; 3],
    /// Index of the block this frame worked on (blocks completed before the frame).
    pub block: u32,
}

/// An iterator as the frame's block queue: the front block is held until the frame pops it.
struct IterSource<I> {
    it: I,
    head: Option<Sealed>,
    /// The frame asked for a block and there was none.
    exhausted: bool,
}

impl<I: Iterator<Item = Sealed>> BlockSource for IterSource<I> {
    fn front(&mut self) -> Option<&Sealed> {
        if self.head.is_none() {
            self.head = self.it.next();
            self.exhausted = self.head.is_none();
        }
        self.head.as_ref()
    }
    fn pop(&mut self) {
        self.head = None;
    }
}

/// Runs `frame` over `blocks` until the last block is done (or `max_ticks` frames have run),
/// with `feed_cap` as the adaptive feed cap of every frame.
pub struct Sim<'f, I: Iterator<Item = Sealed>> {
    frame: &'f mut Frame,
    blocks: IterSource<I>,
    tick: u64,
    max_ticks: u64,
    feed_cap: u32,
    rate: Rate,
}

impl<'f, I: Iterator<Item = Sealed>> Sim<'f, I> {
    pub fn new(frame: &'f mut Frame, blocks: I, feed_cap: u32, max_ticks: u64) -> Self {
        let rate = frame.rate();
        Sim {
            frame,
            blocks: IterSource {
                it: blocks,
                head: None,
                exhausted: false,
            },
            tick: 0,
            max_ticks,
            feed_cap,
            rate,
        }
    }
}

impl<I: Iterator<Item = Sealed>> Iterator for Sim<'_, I> {
    type Item = SimFrame;

    fn next(&mut self) -> Option<SimFrame> {
        if self.tick >= self.max_ticks {
            return None;
        }
        let block = self.frame.blocks_done();
        self.blocks.exhausted = false;
        let pulses = self.frame.tick(&mut self.blocks, self.feed_cap);
        // The end: an idle frame that found no block. (A frame that ends a block also looks for
        // the next one to chain; it is the last frame, not past the end.)
        if self.blocks.exhausted && self.frame.idle() && self.frame.blocks_done() == block {
            return None;
        }
        let out = SimFrame {
            tick: self.tick,
            rate: self.rate,
            pulses,
            position: self.frame.position(),
            block,
        };
        self.tick += 1;
        self.rate = self.frame.rate();
        Some(out)
    }
}
