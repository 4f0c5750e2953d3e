//! Frames: titled, coloured boxes behind a set of nodes ([`FrameDef`]), as Blender's frame and
//! Nuke's backdrop. A frame's box is the bounding box of its nodes, so it follows them, and
//! dragging it moves them. Frames do nothing to evaluation. A node is in at most one frame; a
//! frame left without nodes is removed.

// Graph errors carry their location (file, node, names) by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::{At, FrameDef, Graph, GraphError, NodeId};
use std::collections::{BTreeMap, BTreeSet};

/// Refuses a frame naming a node that does not exist, and a node in two frames (or twice in
/// one), naming the frame by its place in the file and its title.
pub(super) fn check_frames(g: &Graph, at: &At) -> Result<(), GraphError> {
    let mut owner: BTreeMap<NodeId, usize> = BTreeMap::new();
    for (index, f) in g.frames.iter().enumerate() {
        let err = |detail: String| GraphError::Frame {
            index,
            title: f.title.clone(),
            detail,
            at: at.clone(),
        };
        for &id in &f.nodes {
            if !g.nodes.contains_key(&id) {
                return Err(err(format!(
                    "names node {id}, which does not exist: remove it from the frame's nodes"
                )));
            }
            if let Some(other) = owner.insert(id, index) {
                return Err(err(if other == index {
                    format!("lists node {id} twice")
                } else {
                    format!(
                        "holds node {id}, which frame {other} {:?} holds too: a node is in at most one frame",
                        g.frames[other].title
                    )
                }));
            }
        }
    }
    Ok(())
}

impl Graph {
    /// The frame (index into [`Graph::frames`]) that holds node `id`.
    #[must_use]
    pub fn frame_of(&self, id: NodeId) -> Option<usize> {
        self.frames.iter().position(|f| f.nodes.contains(&id))
    }

    /// Puts a new frame around the existing nodes of `ids` (taken out of the frames they were
    /// in). Returns its index, or `None` when no node of `ids` exists.
    pub fn add_frame(&mut self, ids: &[NodeId], title: &str, color: [u8; 3]) -> Option<usize> {
        let mut nodes: Vec<NodeId> = ids
            .iter()
            .copied()
            .filter(|id| self.nodes.contains_key(id))
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        if nodes.is_empty() {
            return None;
        }
        let set: BTreeSet<NodeId> = nodes.iter().copied().collect();
        self.forget_in_frames(&set);
        self.frames.push(FrameDef {
            title: title.to_string(),
            color,
            nodes,
        });
        Some(self.frames.len() - 1)
    }

    /// Takes `ids` out of every frame (nodes deleted or grouped); frames left empty are
    /// removed.
    pub fn forget_in_frames(&mut self, ids: &BTreeSet<NodeId>) {
        for f in &mut self.frames {
            f.nodes.retain(|n| !ids.contains(n));
        }
        self.frames.retain(|f| !f.nodes.is_empty());
    }

    /// Moves every node of frame `index` by `delta`.
    pub fn move_frame(&mut self, index: usize, delta: [f32; 2]) {
        let Some(f) = self.frames.get(index) else {
            return;
        };
        for id in &f.nodes {
            if let Some(n) = self.nodes.get_mut(id) {
                n.pos = [n.pos[0] + delta[0], n.pos[1] + delta[1]];
            }
        }
    }
}
