//! Placeholder: every primitive in one leaf, until the Wald-Havran sweep lands.

use super::{BuildOptions, BuiltTree, Primitives};
use crate::tree::Node;

pub(crate) fn build(prims: &Primitives, _options: &BuildOptions) -> BuiltTree {
    let n = prims.triangles.len() as u32;
    BuiltTree {
        nodes: vec![Node::leaf(0, n)],
        refs: (0..n).collect(),
        ..BuiltTree::default()
    }
}
