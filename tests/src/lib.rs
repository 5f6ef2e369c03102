//! End-to-end tests live in `tests/`. The library holds what they share with the tools
//! that run the same worlds outside the test harness: the world generators
//! ([`generate`]), and what the `worlds` and `paired` binaries need.

pub mod generate;
pub mod judge;
pub mod stats;
pub mod suites;
