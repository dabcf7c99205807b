//! What a build reports about itself, beside the tree.

use serde::Serialize;

/// Timings and per-level profile of one build.
#[derive(Clone, Debug, Default, Serialize)]
pub struct BuildReport {
    /// Wall time of the whole build: the check of the corners, the pre-sort, the tree and its
    /// working memory freed (and handed back, on big meshes).
    pub build_ms: f64,
    /// Wall time of the one-off sort of the primitives (0 for builders that do not sort).
    pub presort_ms: f64,
    /// Peak bytes of the builder's working arrays (not counting the finished tree).
    pub peak_working_bytes: usize,
    /// One entry per tree level, for the breadth-first builders (the hybrid builder: the
    /// levels before its hand-over).
    pub levels: Vec<LevelReport>,
    /// The subtrees built depth first by the exact sweep: the hybrid's after its level passes
    /// (wall time), or the binned build's below its threshold (time of the workers, summed:
    /// built at once, they overlap in wall time); 0 for the others.
    pub subtrees_ms: f64,
    /// Binned builds: pricing and partitioning the binned nodes at the top of the tree, the
    /// workers' time summed.
    pub binned_ms: f64,
    /// Placing the parts of the tree in its final layout and making the tree of them: wall
    /// time.
    pub layout_ms: f64,
}

/// One level of a breadth-first build.
#[derive(Clone, Debug, Default, Serialize)]
pub struct LevelReport {
    pub depth: u32,
    /// Nodes of the level, split or not.
    pub nodes: usize,
    /// Nodes of the level that became leaves.
    pub leaves: usize,
    /// Candidate planes priced.
    pub candidates: usize,
    /// Primitive references held by the level's nodes.
    pub references: usize,
    /// Space-tree counting only: tree nodes visited over all candidates.
    pub walk_steps: u64,
    /// Space-tree counting only: primitives cut by the candidates, summed (the paper's NP).
    pub cut_primitives: u64,
    pub ms: PhaseTimes,
}

/// Wall time of each phase of a level, in milliseconds.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PhaseTimes {
    pub candidates: f64,
    pub space_trees: f64,
    pub counting: f64,
    pub decision: f64,
    pub partition: f64,
}
