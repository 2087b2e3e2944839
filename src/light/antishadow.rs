//! Antishadow geometry (to be written).
