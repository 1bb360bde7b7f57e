//! millac host tool entry point (host).
fn main() {}
