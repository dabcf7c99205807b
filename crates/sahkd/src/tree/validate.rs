//! Structure and completeness checks for any tree, whichever builder made it.

use super::KdTree;
use crate::clip;
use crate::geometry::{Aabb, Vec3};

/// Triangles checked for completeness: all of them up to this count, a fixed sample above.
const COMPLETENESS_SAMPLE: usize = 200_000;

/// Checks that
/// - every node is reached exactly once from the root, children and leaf ranges are in
///   bounds, every reference names a triangle, every split lies strictly inside its node;
/// - every triangle that overlaps a leaf's box (shrunk by a hair, so that touching the
///   boundary does not count) is referenced by that leaf. On trees of more than 200 000
///   triangles, an evenly spaced sample of 200 000 is checked.
pub fn validate(tree: &KdTree) -> Result<(), String> {
    check_structure(tree)?;
    check_completeness(tree)
}

fn check_structure(tree: &KdTree) -> Result<(), String> {
    let nodes = &tree.nodes;
    if nodes.is_empty() {
        return Err("the tree has no root node".into());
    }
    // Children after their parent rules out cycles, and in-range children make the walk
    // below safe to index.
    for (i, node) in nodes.iter().enumerate() {
        if !node.is_leaf() && (node.left() as usize <= i || node.left() as usize + 1 >= nodes.len())
        {
            return Err(format!(
                "node {i} has children at {} and {}, not after it and within the {} nodes",
                node.left(),
                node.left() + 1,
                nodes.len()
            ));
        }
    }
    let mut seen = vec![false; nodes.len()];
    let mut reached = 0usize;
    let mut failure = None;
    tree.visit(|i, node, bounds, _| {
        if failure.is_some() {
            return;
        }
        let i = i as usize;
        if seen[i] {
            failure = Some(format!("node {i} is reached twice"));
            return;
        }
        seen[i] = true;
        reached += 1;
        if node.is_leaf() {
            let end = node.first() as usize + node.count() as usize;
            if end > tree.refs.len() {
                failure = Some(format!("leaf {i} ends at reference {end}, past the end"));
            } else if let Some(&r) = tree
                .leaf_refs(node)
                .iter()
                .find(|&&r| r as usize >= tree.triangles.len())
            {
                failure = Some(format!(
                    "leaf {i} references triangle {r}, which does not exist"
                ));
            }
        } else {
            let (axis, split) = (node.axis(), node.split());
            if !(split > bounds.lo[axis] && split < bounds.hi[axis]) {
                failure = Some(format!(
                    "node {i} splits axis {axis} at {split}, outside its box {:?}..{:?}",
                    bounds.lo[axis], bounds.hi[axis]
                ));
            }
        }
    });
    if let Some(f) = failure {
        return Err(f);
    }
    if reached != nodes.len() {
        return Err(format!(
            "{} of {} nodes are not reachable from the root",
            nodes.len() - reached,
            nodes.len()
        ));
    }
    Ok(())
}

fn check_completeness(tree: &KdTree) -> Result<(), String> {
    let n = tree.triangles.len();
    if n == 0 {
        return Ok(());
    }
    let step = n.div_ceil(COMPLETENESS_SAMPLE).max(1);
    let scale = tree
        .bounds
        .extent()
        .0
        .iter()
        .fold(0f32, |m, &d| m.max(d.abs()));
    let hair = (scale * 1e-5).max(f32::MIN_POSITIVE);
    let mut stack = Vec::new();
    for t in (0..n).step_by(step) {
        let tri = &tree.triangles[t];
        stack.clear();
        stack.push((0u32, tree.bounds));
        while let Some((i, bounds)) = stack.pop() {
            let node = &tree.nodes[i as usize];
            if node.is_leaf() {
                if tree.leaf_refs(node).binary_search(&(t as u32)).is_err() {
                    return Err(format!(
                        "triangle {t} overlaps leaf {i} (box {:?}..{:?}) but is not referenced by it",
                        bounds.lo.0, bounds.hi.0
                    ));
                }
                continue;
            }
            let (l, r) = bounds.split(node.axis(), node.split());
            for (child, b) in [(node.left(), l), (node.left() + 1, r)] {
                if clip::overlaps(tri, &shrink(&b, hair)) {
                    stack.push((child, b));
                }
            }
        }
    }
    Ok(())
}

fn shrink(b: &Aabb, by: f32) -> Aabb {
    Aabb::new(b.lo + Vec3::splat(by), b.hi - Vec3::splat(by))
}
