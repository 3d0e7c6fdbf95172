//! geodata (scaffold, being written).
