//! The session: the open document and what is selected and viewed in it, the node clipboard,
//! and when it was last autosaved.

use super::state::Document;
use super::structure::Entered;
use crate::graph::{Graph, NodeDef, NodeId};
use std::time::Instant;

/// The open document and its selection.
pub struct Session {
    /// The document.
    pub doc: Document,
    /// Bumped for every new document (stale clipboard edges, undo grouping).
    pub(super) doc_epoch: u64,
    /// The node whose parameters the inspector shows.
    pub selected: Option<NodeId>,
    /// The node shown in the preview, and which of its outputs.
    pub viewed: Option<(NodeId, String)>,
    /// Copied nodes and the document epoch they were copied in.
    pub(super) clipboard: Option<(u64, Vec<NodeDef>)>,
    pub(super) last_autosave: Instant,
    /// The graph last written to the recovery file (not written again until it changes).
    pub(super) autosaved: Option<Graph>,
    /// Groups entered in place, outermost first ([`super::structure_ui`]); empty at the top.
    pub groups: Vec<Entered>,
}

impl Session {
    /// A session on `doc`, viewing its default output.
    pub(super) fn new(doc: Document) -> Self {
        let viewed = default_view(&doc.graph);
        Self {
            selected: viewed.as_ref().map(|v| v.0),
            viewed,
            doc,
            doc_epoch: 0,
            clipboard: None,
            last_autosave: Instant::now(),
            autosaved: None,
            groups: Vec::new(),
        }
    }
}

/// What to view first: the node behind the graph's `image` output, else its first output.
pub(super) fn default_view(g: &Graph) -> Option<(NodeId, String)> {
    let r = g
        .outputs
        .get("image")
        .or_else(|| g.outputs.values().next())?;
    Some((r.node, r.port.clone()))
}
