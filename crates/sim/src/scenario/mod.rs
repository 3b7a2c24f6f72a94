//! Scenarios of `truepos simulate`: each builds a data set and its truth for one capability.

pub mod head_offset;
pub mod latency;
pub mod load;
pub mod somac;
