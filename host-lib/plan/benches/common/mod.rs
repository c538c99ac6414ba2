//! What the plan benchmarks share (see each module).

pub mod finger_part;
