//! evigrid (scaffold, being written).
