//! millac boards: pin and timer bindings per board, used by the RTIC app (firmware contexts).
#![no_std]
