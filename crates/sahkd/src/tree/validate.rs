//! Structure and completeness checks for any tree, whichever builder made it.

use super::KdTree;
use crate::clip;
use crate::cost::MAX_DEPTH_CAP;
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
    check_completeness(tree, COMPLETENESS_SAMPLE)
}

fn check_structure(tree: &KdTree) -> Result<(), String> {
    let nodes = &tree.nodes;
    if nodes.is_empty() {
        return Err("the tree has no root node".into());
    }
    // Children after their parent rules out cycles, in-range children make the walk below
    // safe to index, and one parent per node makes it a tree (not a DAG walked exponentially).
    let mut parents = vec![0u8; nodes.len()];
    for (i, node) in nodes.iter().enumerate() {
        if node.is_leaf() {
            continue;
        }
        let left = node.left() as usize;
        if left <= i || left + 1 >= nodes.len() {
            return Err(format!(
                "node {i} has children at {left} and {}, not after it and within the {} nodes",
                left + 1,
                nodes.len()
            ));
        }
        for child in [left, left + 1] {
            parents[child] += 1;
            if parents[child] > 1 {
                return Err(format!("node {child} has more than one parent"));
            }
        }
    }
    let mut seen = vec![false; nodes.len()];
    let mut reached = 0usize;
    let mut failure = None;
    tree.visit(|i, node, bounds, depth| {
        if failure.is_some() {
            return;
        }
        if depth > MAX_DEPTH_CAP {
            failure = Some(format!(
                "node {i} lies at depth {depth}, past the cap of {MAX_DEPTH_CAP}"
            ));
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

/// Every split strictly inside its node's box and every leaf's references sorted, on a tree
/// whose structure is known sound (each node reached once from the root). The top levels are
/// walked here, the subtrees below them on the worker threads.
pub(crate) fn check_splits(tree: &KdTree) -> Result<(), String> {
    use rayon::prelude::*;
    let mut frontier = vec![(0u32, tree.bounds)];
    while frontier.len() < 256
        && frontier
            .iter()
            .any(|&(i, _)| !tree.nodes[i as usize].is_leaf())
    {
        let mut next = Vec::with_capacity(2 * frontier.len());
        for (i, bounds) in frontier {
            check_node(tree, i, &bounds, &mut next)?;
        }
        frontier = next;
    }
    frontier.par_iter().try_for_each(|&(i, bounds)| {
        // Down the left children without the stack; right children wait on it.
        let mut stack = Vec::new();
        let (mut i, mut bounds) = (i, bounds);
        loop {
            let node = &tree.nodes[i as usize];
            if node.is_leaf() {
                if !tree.leaf_refs(node).is_sorted() {
                    return Err(format!("leaf {i}'s references are not sorted"));
                }
                match stack.pop() {
                    Some(next) => (i, bounds) = next,
                    None => return Ok(()),
                }
                continue;
            }
            let (axis, split) = (node.axis(), node.split());
            check_split(i, axis, split, &bounds)?;
            let mut right = bounds;
            right.lo[axis] = split;
            stack.push((node.left() + 1, right));
            bounds.hi[axis] = split;
            i = node.left();
        }
    })
}

/// A split strictly inside its node's box.
#[inline(always)]
fn check_split(i: u32, axis: usize, split: f32, bounds: &Aabb) -> Result<(), String> {
    if split > bounds.lo[axis] && split < bounds.hi[axis] {
        return Ok(());
    }
    Err(format!(
        "node {i} splits axis {axis} at {split}, outside its box {:?}..{:?}",
        bounds.lo[axis], bounds.hi[axis]
    ))
}

/// Checks node `i` with its box, and pushes its children (left on top) onto `pending`.
#[inline]
fn check_node(
    tree: &KdTree,
    i: u32,
    bounds: &Aabb,
    pending: &mut Vec<(u32, Aabb)>,
) -> Result<(), String> {
    let node = &tree.nodes[i as usize];
    if node.is_leaf() {
        if !tree.leaf_refs(node).is_sorted() {
            return Err(format!("leaf {i}'s references are not sorted"));
        }
        return Ok(());
    }
    let (axis, split) = (node.axis(), node.split());
    check_split(i, axis, split, bounds)?;
    let (l, r) = bounds.split(axis, split);
    pending.push((node.left() + 1, r));
    pending.push((node.left(), l));
    Ok(())
}

/// Completeness of the leaves for every triangle up to `sample` of them, an evenly spaced
/// sample of `sample` above.
pub(crate) fn check_completeness(tree: &KdTree, sample: usize) -> Result<(), String> {
    let n = tree.triangles.len();
    if n == 0 {
        return Ok(());
    }
    let step = n.div_ceil(sample.max(1)).max(1);
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

#[cfg(test)]
mod tests {
    use crate::geometry::{triangle_bounds, Triangle, Vec3};
    use crate::tree::{KdTree, Node};

    /// Two triangles, one each side of x = 1, under a hand-made split at x = 1.
    fn two_triangles() -> Vec<Triangle> {
        vec![
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.9, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            [
                Vec3::new(1.1, 0.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(2.0, 1.0, 1.0),
            ],
        ]
    }

    fn tree(nodes: Vec<Node>, refs: Vec<u32>) -> KdTree {
        let tris = two_triangles();
        let bounds = triangle_bounds(&tris[0]).union(triangle_bounds(&tris[1]));
        KdTree::from_parts(tris, bounds, nodes, refs)
    }

    #[test]
    fn a_correct_hand_made_tree_passes() {
        let t = tree(
            vec![
                Node::interior(0, 1.0, 1),
                Node::leaf(0, 1),
                Node::leaf(1, 1),
            ],
            vec![0, 1],
        );
        assert_eq!(t.validate(), Ok(()));
    }

    #[test]
    fn a_missing_reference_is_found() {
        let t = tree(
            vec![
                Node::interior(0, 1.0, 1),
                Node::leaf(0, 1),
                Node::leaf(1, 0),
            ],
            vec![0],
        );
        let e = t.validate().unwrap_err();
        assert!(
            e.contains("triangle 1") && e.contains("not referenced"),
            "{e}"
        );
    }

    #[test]
    fn broken_structure_is_found() {
        let cases = [
            (
                vec![
                    Node::interior(0, 5.0, 1),
                    Node::leaf(0, 1),
                    Node::leaf(1, 1),
                ],
                "outside its box",
            ),
            (
                vec![
                    Node::interior(0, 1.0, 1),
                    Node::leaf(0, 1),
                    Node::leaf(1, 2),
                ],
                "past the end",
            ),
            (
                vec![Node::interior(0, 1.0, 0), Node::leaf(0, 1)],
                "not after it",
            ),
            (
                vec![
                    Node::interior(0, 1.0, 1),
                    Node::interior(1, 0.5, 2),
                    Node::leaf(0, 1),
                    Node::leaf(1, 1),
                ],
                "more than one parent",
            ),
            (vec![Node::leaf(0, 1), Node::leaf(1, 1)], "not reachable"),
        ];
        for (nodes, expected) in cases {
            let e = tree(nodes, vec![0, 1]).validate().unwrap_err();
            assert!(e.contains(expected), "{e} (expected '{expected}')");
        }
    }
}
