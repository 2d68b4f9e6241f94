//! Experiments: each one a scenario struct (TOML, documented defaults), a
//! pure function that runs it, and a result struct the CLI prints and writes.
//! The paper reproductions of spec 10–30 land here as their issues do.

pub mod anomalies;
pub mod consistency;
pub mod outages;
