//! sim (scaffold, being written).
