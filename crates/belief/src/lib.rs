//! belief (scaffold, being written).
