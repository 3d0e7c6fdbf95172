//! The transform tree of a recording (`/tf`, `/tf_static`, or odometry seen as one edge), and the
//! chain from a fixed frame down to the cloud's frame.
//!
//! tf is a tree: every frame has at most one parent. An edge is static (one transform, from
//! `/tf_static`) or dynamic (transforms at increasing times, interpolated through
//! [`PoseTrack`]). The track of a chain is sampled at the times of its dynamic edge with the most
//! samples; other dynamic edges are interpolated there, and times where one of them has no pose
//! are left out.

use crate::poses::PoseTrack;
use nalgebra::Isometry3;
use std::collections::BTreeMap;

use super::msgs::StampedTransform;

/// tf frame names are written with or without a leading slash (ROS 1 habit); compare without.
pub(crate) fn frame_key(name: &str) -> &str {
    name.strip_prefix('/').unwrap_or(name)
}

/// One edge of the tree: `parent_from_child`.
#[derive(Debug, Clone)]
enum Edge {
    Static(Isometry3<f64>),
    /// Samples as received; sorted and deduplicated by [`TfTree::finish`].
    Dynamic(Vec<(f64, Isometry3<f64>)>),
}

/// Transforms gathered from a recording, keyed by child frame.
#[derive(Debug, Clone, Default)]
pub(crate) struct TfTree {
    edges: BTreeMap<String, (String, Edge)>,
}

impl TfTree {
    /// Adds a transform. A child that changes parent is an error (tf allows one parent).
    pub(crate) fn add(&mut self, t: StampedTransform, is_static: bool) -> Result<(), String> {
        let child = frame_key(&t.child).to_owned();
        let parent = frame_key(&t.parent).to_owned();
        if child == parent {
            return Err(format!("frame `{child}` is its own parent"));
        }
        match self.edges.get_mut(&child) {
            Some((p, _)) if *p != parent => Err(format!(
                "frame `{child}` has two parents, `{p}` and `{parent}`"
            )),
            Some((_, edge)) => {
                match edge {
                    // A re-published static transform replaces the old one.
                    Edge::Static(x) if is_static => *x = t.parent_from_child,
                    Edge::Dynamic(v) if !is_static => v.push((t.stamp_s, t.parent_from_child)),
                    _ => {
                        return Err(format!(
                            "frame `{child}` is published both on /tf and /tf_static"
                        ));
                    }
                }
                Ok(())
            }
            None => {
                let edge = if is_static {
                    Edge::Static(t.parent_from_child)
                } else {
                    Edge::Dynamic(vec![(t.stamp_s, t.parent_from_child)])
                };
                self.edges.insert(child, (parent, edge));
                Ok(())
            }
        }
    }

    /// Sorts dynamic samples by time and drops repeated times (keeping the first).
    pub(crate) fn finish(&mut self) {
        for (_, edge) in self.edges.values_mut() {
            if let Edge::Dynamic(v) = edge {
                v.sort_by(|a, b| a.0.total_cmp(&b.0));
                v.dedup_by(|b, a| b.0 == a.0);
            }
        }
    }

    /// True when no transform was seen.
    pub(crate) fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// The frames from `frame` up to its root, `frame` first.
    fn ancestors(&self, frame: &str) -> Vec<String> {
        let mut out = vec![frame_key(frame).to_owned()];
        while let Some((parent, _)) = out.last().and_then(|f| self.edges.get(f)) {
            // A cycle (a corrupt tree) ends the walk.
            if out.contains(parent) {
                break;
            }
            out.push(parent.clone());
        }
        out
    }

    /// The root above `frame` (the frame itself when it has no parent).
    pub(crate) fn root_of(&self, frame: &str) -> String {
        self.ancestors(frame)
            .pop()
            .unwrap_or_else(|| frame.to_owned())
    }

    /// The static transform `from_from_to` when every edge between them is static, else `None`.
    /// `to` must lie below `from` (or be it).
    pub(crate) fn static_chain(&self, from: &str, to: &str) -> Option<Isometry3<f64>> {
        let up = self.ancestors(to);
        let k = up.iter().position(|f| f == frame_key(from))?;
        let mut out = Isometry3::identity();
        for child in up[..k].iter().rev() {
            match self.edges.get(child) {
                Some((_, Edge::Static(x))) => out *= x,
                _ => return None,
            }
        }
        Some(out)
    }

    /// A description of the tree for error messages: `parent -> child (static|N samples)`.
    pub(crate) fn describe(&self) -> String {
        if self.edges.is_empty() {
            return "no transforms".to_owned();
        }
        self.edges
            .iter()
            .map(|(child, (parent, edge))| match edge {
                Edge::Static(_) => format!("{parent} -> {child} (static)"),
                Edge::Dynamic(v) => format!("{parent} -> {child} ({} samples)", v.len()),
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The track of `fixed_from_frame`: the chain from `fixed` down to `frame`.
    ///
    /// # Errors
    ///
    /// A message when `fixed` is not above `frame`, the chain has no dynamic edge (a track needs
    /// times), or no time has a pose on every dynamic edge.
    pub(crate) fn track(&self, fixed: &str, frame: &str) -> Result<PoseTrack, String> {
        let up = self.ancestors(frame);
        let Some(k) = up.iter().position(|f| f == frame_key(fixed)) else {
            return Err(format!(
                "no tf chain from `{fixed}` to `{frame}`; `{frame}` goes up to: {}; tree: {}",
                up.join(" -> "),
                self.describe()
            ));
        };
        // Edges from the fixed frame down, as tracks or static transforms.
        let mut chain = Vec::with_capacity(k);
        for child in up[..k].iter().rev() {
            let Some((_, edge)) = self.edges.get(child) else {
                return Err(format!("no edge above `{child}`"));
            };
            chain.push(match edge {
                Edge::Static(x) => Err(*x),
                Edge::Dynamic(v) => {
                    let (times, poses) = v.iter().copied().unzip();
                    Ok(PoseTrack::new(times, poses)
                        .map_err(|e| format!("tf edge above `{child}`: {e}"))?)
                }
            });
        }
        let Some(base) = chain
            .iter()
            .filter_map(|e| e.as_ref().ok())
            .max_by_key(|t| t.len())
        else {
            return Err(format!(
                "the tf chain from `{fixed}` to `{frame}` is all static: no motion to make a \
                 track of"
            ));
        };
        let mut times = Vec::with_capacity(base.len());
        let mut poses = Vec::with_capacity(base.len());
        'time: for &t in base.times() {
            let mut pose = Isometry3::identity();
            for edge in &chain {
                match edge {
                    Err(x) => pose *= x,
                    Ok(track) => match track.at(t) {
                        Ok(x) => pose *= x,
                        Err(_) => continue 'time,
                    },
                }
            }
            times.push(t);
            poses.push(pose);
        }
        PoseTrack::new(times, poses).map_err(|e| {
            format!(
                "tf chain from `{fixed}` to `{frame}`: {e} (no time where every moving edge has \
                 a pose?)"
            )
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn st(t: f64, parent: &str, child: &str, x: f64, yaw: f64) -> StampedTransform {
        StampedTransform {
            stamp_s: t,
            parent: parent.into(),
            child: child.into(),
            parent_from_child: Isometry3::from_parts(
                Translation3::new(x, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            ),
        }
    }

    #[test]
    fn chains_static_and_dynamic_edges() {
        let mut tf = TfTree::default();
        tf.add(st(0.0, "base_link", "/lidar", 1.0, 0.0), true)
            .unwrap();
        tf.add(st(0.0, "map", "odom", 100.0, 0.0), true).unwrap();
        // Out of order on purpose.
        tf.add(st(1.0, "odom", "base_link", 10.0, 0.0), false)
            .unwrap();
        tf.add(st(0.0, "odom", "base_link", 0.0, 0.0), false)
            .unwrap();
        tf.finish();
        assert_eq!(tf.root_of("lidar"), "map");
        let track = tf.track("map", "lidar").unwrap();
        assert_eq!(track.times(), &[0.0, 1.0]);
        let mid = track.at(0.5).unwrap();
        assert!((mid.translation.vector.x - 106.0).abs() < 1e-12);
        let odom = tf.track("/odom", "lidar").unwrap();
        assert!((odom.at(1.0).unwrap().translation.vector.x - 11.0).abs() < 1e-12);
        assert!(tf.static_chain("base_link", "lidar").is_some());
        assert!(tf.static_chain("odom", "lidar").is_none());
        let err = tf.track("world", "lidar").unwrap_err();
        assert!(err.contains("lidar -> base_link -> odom -> map"), "{err}");
        assert!(
            tf.track("base_link", "lidar")
                .unwrap_err()
                .contains("static")
        );
    }

    #[test]
    fn two_parents_and_mixed_edges_are_refused() {
        let mut tf = TfTree::default();
        tf.add(st(0.0, "a", "b", 1.0, 0.0), false).unwrap();
        assert!(tf.add(st(1.0, "c", "b", 1.0, 0.0), false).is_err());
        assert!(tf.add(st(1.0, "a", "b", 1.0, 0.0), true).is_err());
        assert!(tf.add(st(1.0, "a", "a", 1.0, 0.0), true).is_err());
    }
}
