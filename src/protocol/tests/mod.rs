//! The grbl protocol on the host (host tests): commands, lines, status reports, the receive
//! ring, and the rig they share (`util`).
mod cmd;
mod lines;
mod report;
mod rx;
mod util;
