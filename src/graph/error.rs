//! Errors of graph files, graph validation and evaluation. Each message is one line: what is
//! wrong first, then where (`node ID "name"`, port or parameter, file).

use crate::error::RgbnError;
use std::fmt;

/// Where in a graph something is: the file and (usually) the node.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct At {
    /// The graph file (or `<memory>` for graphs not read from a file).
    pub file: String,
    /// The node id, if the problem is at a node.
    pub node: Option<u64>,
    /// The node's name, if it has one.
    pub name: Option<String>,
}

impl At {
    /// The node alone (`node 3 "name"`), or the file when not at a node.
    #[must_use]
    pub fn short(&self) -> String {
        match (self.node, &self.name) {
            (Some(id), Some(n)) => format!("node {id} {n:?}"),
            (Some(id), None) => format!("node {id}"),
            _ => self.file.clone(),
        }
    }

    /// A location in `file`, at no particular node.
    #[must_use]
    pub fn file(file: impl Into<String>) -> Self {
        Self {
            file: file.into(),
            node: None,
            name: None,
        }
    }
    /// The same file, at node `id` named `name`.
    #[must_use]
    pub fn node(&self, id: u64, name: Option<&str>) -> Self {
        Self {
            file: self.file.clone(),
            node: Some(id),
            name: name.map(str::to_string),
        }
    }
}

impl fmt::Display for At {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(id) = self.node {
            write!(f, "node {id}")?;
            if let Some(n) = &self.name {
                write!(f, " {n:?}")?;
            }
            write!(f, " in ")?;
        }
        write!(f, "{}", self.file)
    }
}

fn suggest(s: &Option<String>) -> String {
    s.as_ref()
        .map(|s| format!(" (did you mean {s:?}?)"))
        .unwrap_or_default()
}

/// Everything that can go wrong reading, checking or evaluating a graph.
#[derive(Debug, thiserror::Error)]
pub enum GraphError {
    /// The graph file could not be read.
    #[error("cannot read graph file ({source}): {file}")]
    Io {
        /// The file.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },

    /// The file is not valid RON, or does not have the shape of a graph file.
    #[error("invalid graph file at line {line}, column {col}: {detail}: {file}")]
    Syntax {
        /// The file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        col: usize,
        /// What the parser expected.
        detail: String,
    },

    /// The file was written by a newer rgbn.
    #[error("graph file version {found} is newer than this rgbn supports ({supported}); update rgbn: {file}")]
    UnsupportedVersion {
        /// The file.
        file: String,
        /// Version in the file.
        found: u32,
        /// Newest version understood.
        supported: u32,
    },

    /// Two nodes share an id.
    #[error("duplicate node id {id}: {at}")]
    DuplicateNode {
        /// The id.
        id: u64,
        /// Where.
        at: At,
    },

    /// `next_id` would hand out an id already used (ids are never reused).
    #[error("next_id {next_id} is not above the largest node id {max}: {at}")]
    NextId {
        /// The file's `next_id`.
        next_id: u64,
        /// Largest id present.
        max: u64,
        /// Where.
        at: At,
    },

    /// No operator has this id.
    #[error("unknown operator {op:?}{}: {at}", suggest(.suggestion))]
    UnknownOp {
        /// The id given.
        op: String,
        /// Nearest operator id.
        suggestion: Option<String>,
        /// Where.
        at: At,
    },

    /// A parameter is unknown, of the wrong kind, or out of range.
    #[error("{detail}: {at}")]
    Param {
        /// The parameter.
        param: String,
        /// What is wrong (names the parameter, suggests the nearest name).
        detail: String,
        /// Where.
        at: At,
    },

    /// A `--set` value could not be parsed for its parameter's kind.
    #[error("cannot set {param:?} to {value:?}: {detail}: {at}")]
    BadValue {
        /// The parameter.
        param: String,
        /// The text given.
        value: String,
        /// Why.
        detail: String,
        /// Where.
        at: At,
    },

    /// An edge names a port the node does not have.
    #[error("no {dir} port {port:?} on {op}{}: {at}", suggest(.suggestion))]
    UnknownPort {
        /// `input` or `output`.
        dir: &'static str,
        /// The port given.
        port: String,
        /// The operator of the node that lacks it.
        op: String,
        /// Nearest port name.
        suggestion: Option<String>,
        /// Where (the node the edge leads to).
        at: At,
    },

    /// An edge or reference names a node that does not exist.
    #[error("{what} refers to missing node {missing}: {at}")]
    MissingNode {
        /// What refers (`input "image"`, `output "relit"`).
        what: String,
        /// The missing id.
        missing: u64,
        /// Where.
        at: At,
    },

    /// A required input port is not connected.
    #[error("required input {port:?} is not connected: {at}")]
    MissingInput {
        /// The port.
        port: String,
        /// Where.
        at: At,
    },

    /// An edge connects ports of different types.
    #[error("type mismatch on input {port:?}: expects {expected}, but {from} gives {found}: {at}")]
    TypeMismatch {
        /// The input port.
        port: String,
        /// Its type.
        expected: &'static str,
        /// The source (`node 2 output "image"`).
        from: String,
        /// The source's type.
        found: &'static str,
        /// Where.
        at: At,
    },

    /// The edges form a cycle.
    #[error("cycle through nodes {nodes:?}: {at}")]
    Cycle {
        /// Nodes on the cycle.
        nodes: Vec<u64>,
        /// Where.
        at: At,
    },

    /// A frame names a node that does not exist, or a node another frame (or itself) already
    /// holds.
    #[error("frame {index} {title:?} {detail}: {at}")]
    Frame {
        /// The frame's place in the file's `frames` list (from 0).
        index: usize,
        /// Its title.
        title: String,
        /// What is wrong (`names node 9, which does not exist`).
        detail: String,
        /// The graph file.
        at: At,
    },

    /// A reroute has nothing feeding it, or an input other than `in`.
    #[error("reroute {detail}: {at}")]
    Reroute {
        /// What is wrong.
        detail: String,
        /// Where (the reroute node).
        at: At,
    },

    /// Graph files use each other as nodes in a loop.
    #[error("graph files use each other in a cycle: {chain}")]
    FileCycle {
        /// `a.ron → b.ron → a.ron`.
        chain: String,
    },

    /// A graph input, output or node named on the command line (or in the file) does not exist.
    #[error("unknown {what} {name:?}{}: {at}", suggest(.suggestion))]
    Unknown {
        /// `graph input`, `graph output`, `node`, `exposed parameter`.
        what: &'static str,
        /// The name given.
        name: String,
        /// Nearest existing name.
        suggestion: Option<String>,
        /// Where.
        at: At,
    },

    /// A graph input needed by the requested outputs was not given.
    #[error("graph input {name:?} is needed but not given (use --input {name}=PATH): {at}")]
    UnboundInput {
        /// The input.
        name: String,
        /// Where.
        at: At,
    },

    /// A file a node reads cannot be read.
    #[error("cannot read input file {path} ({detail}): {at}")]
    InputFile {
        /// The file.
        path: String,
        /// Why.
        detail: String,
        /// Where (the node that reads it).
        at: At,
    },

    /// An operator failed while evaluating.
    #[error("{op} failed: {source}: {at}")]
    Node {
        /// The operator id.
        op: String,
        /// The underlying error.
        source: RgbnError,
        /// Where.
        at: At,
    },

    /// Evaluation was cancelled.
    #[error("evaluation cancelled")]
    Cancelled,

    /// The plan's estimated peak memory is over the budget (see `eval::memory`).
    #[error(
        "evaluating needs about {need} of memory, over the budget of {budget} \
         (RGBN_MEMORY_LIMIT; default 80 % of physical memory): {nodes}; evaluate fewer or \
         smaller images, or raise RGBN_MEMORY_LIMIT: {at}"
    )]
    Memory {
        /// Estimated peak.
        need: String,
        /// The budget.
        budget: String,
        /// The nodes needing the most.
        nodes: String,
        /// The graph.
        at: At,
    },

    /// An environment variable holds a value that cannot be used.
    #[error("environment variable {var}: {detail}")]
    Env {
        /// The variable.
        var: &'static str,
        /// What is wrong.
        detail: String,
    },
}

impl GraphError {
    /// Operator `op` at `at` failed with `source`; a cancelled operator is
    /// [`GraphError::Cancelled`], whichever node saw it.
    #[must_use]
    pub fn node(op: impl Into<String>, source: RgbnError, at: At) -> Self {
        match source {
            RgbnError::Cancelled => GraphError::Cancelled,
            source => GraphError::Node {
                op: op.into(),
                source,
                at,
            },
        }
    }
}
