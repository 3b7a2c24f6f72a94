//! The virtual cell's scenarios, one module per capability: the data set a `truepos simulate`
//! scenario writes (with its `truth.json`) and the capability's section of the demo report,
//! which runs the capability on the virtual plant and compares the result with the truth.

pub mod align;
pub mod head;
pub mod interfaces;
pub mod latency;
pub mod load;
pub mod nist;
pub mod part;
pub mod scan;
pub mod somac;
