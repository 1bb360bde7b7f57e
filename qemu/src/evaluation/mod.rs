//! Evaluation (host): reports, benchmarks, reproductions of the papers, offline optimisation and
//! the model-based method, the monitors' labs, plots.
pub mod acreport;
pub mod alarmlab;
pub mod bench;
pub mod breaklab;
pub mod chatterlab;
pub mod heightmap;
pub mod job;
pub mod model;
pub mod optimise;
pub mod plot;
pub mod raster;
pub mod repro;
