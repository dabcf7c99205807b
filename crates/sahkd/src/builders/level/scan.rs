//! Scan counting: running counts over each node's position-sorted events.
//!
//! On an axis, a node's events (start at lo, end at hi, one planar event when lo == hi) are
//! sorted by position. The distinct positions strictly inside the node are its candidates (a
//! position shared by several lo/hi values is priced once; the copies would price the same).
//! For a run of events at position `p`, with the counts of each kind before the run and in it:
//! - `L = #(lo < p)` = starts + planars before the run,
//! - `R = #(hi > p) = n - #(hi <= p)` = n - (ends + planars before and in the run),
//! - `P` = planars in the run.
//!
//! So a node's candidates are counted by one sweep over its events: O(n) per node. Nodes are
//! swept in parallel; a large node is itself cut into chunks whose counts-before come from a
//! prefix sum over the chunks' counts, so that the top levels are as parallel as the rest.
//! Counting, pricing and the per-axis part of the segmented min are one pass here (timed as
//! counting): each (node, axis) pair leaves only its best candidate in the level's candidate
//! array, and the decision takes the min over a node's axes. Writing every candidate out to
//! read it back once costs a quarter of the level's counting time and buys nothing.

use super::candidates::{self, Candidate, Candidates, Counts};
use super::entries::{Event, END, PLANAR, START};
use super::segments::CHUNK;
use super::{ms_since, Level};
use crate::builders::LevelReport;
use crate::cost::{CostModel, SplitPricer};
use crate::geometry::Aabb;
use rayon::prelude::*;
use std::time::Instant;

/// Segments from this size on are swept in parallel chunks.
const PARALLEL_SWEEP: usize = 2 * CHUNK;

/// Phases 1 and 3 for every node and axis: the candidates of the level, counted and priced.
pub(super) fn price(
    level: &Level<Event>,
    uses: &[u8],
    cost: &CostModel,
    cands: &mut Candidates,
    report: &mut LevelReport,
) {
    let t = Instant::now();
    let nodes = level.nodes();
    let seg = |axis: usize, k: usize| {
        let s = &level.list_starts[axis];
        &level.lists[axis][s[k] as usize..s[k + 1] as usize]
    };
    // One slot per priced (node, axis) pair: its best candidate.
    cands.lay_out(nodes, |axis, k| (uses[k] >> axis) as usize & 1);
    report.ms.candidates += ms_since(t);
    let t = Instant::now();
    let fill = cands.filler();
    let priced: usize = (0..nodes)
        .into_par_iter()
        .with_min_len(32)
        .map(|k| {
            let mut priced = 0;
            for axis in 0..3 {
                if uses[k] & (1 << axis) == 0 {
                    continue;
                }
                let events = seg(axis, k);
                let node = Node {
                    n: level.refs(k),
                    bbox: &level.boxes[k],
                    axis,
                    owner: k as u32,
                    splits: cost.splits_of(&level.boxes[k], axis),
                };
                let found = if events.len() >= PARALLEL_SWEEP {
                    sweep_chunks(events, &node)
                } else {
                    sweep(events, 0, events.len(), [0; 3], &node)
                };
                // Safety: this task owns node k's pairs.
                unsafe {
                    let at = fill.first(axis, k);
                    match found.best {
                        Some(c) => {
                            fill.write(at, c);
                            fill.finish(axis, k, 1);
                        }
                        None => fill.finish(axis, k, 0),
                    }
                }
                priced += found.priced;
            }
            priced
        })
        .sum();
    cands.priced = priced;
    report.ms.counting += ms_since(t);
}

/// What a sweep found: how many candidates it priced and the best of them.
#[derive(Clone, Copy, Default)]
struct Found {
    priced: usize,
    best: Option<Candidate>,
}

impl Found {
    /// The candidate kept, by the builders' one order (all on one axis here).
    fn offer(&mut self, c: Candidate) {
        self.priced += 1;
        match &self.best {
            Some(b) if !c.ranked(0).precedes(b.ranked(0)) => {}
            _ => self.best = Some(c),
        }
    }
    fn join(mut self, o: Found) -> Found {
        let priced = self.priced + o.priced;
        if let Some(c) = o.best {
            self.offer(c);
        }
        self.priced = priced;
        self
    }
}

/// What a sweep needs to know of its node.
struct Node<'a> {
    n: u32,
    bbox: &'a Aabb,
    axis: usize,
    owner: u32,
    /// The node's split costs along the axis, prepared once per sweep.
    splits: SplitPricer,
}

/// Counts and prices the runs that start in `events[from..to]`, where `events` is one node's
/// segment and `before` the counts of each kind in `events[..from]`. A run may go on past
/// `to` (to the end of the segment); a run going on at `from` belongs to whoever has its
/// start.
fn sweep(events: &[Event], from: usize, to: usize, before: [u32; 3], node: &Node) -> Found {
    let (lo, hi) = (node.bbox.lo[node.axis], node.bbox.hi[node.axis]);
    // Running counts in registers: starts + planars (the lo values) and ends + planars (the hi
    // values) before the current run.
    let (s, pl, e) = (START as usize, PLANAR as usize, END as usize);
    let mut los = before[s] + before[pl];
    let mut his = before[e] + before[pl];
    let mut i = from;
    if i > 0 && i < to {
        let bits = events[i - 1].pos_bits();
        while i < events.len() && events[i].pos_bits() == bits {
            let kind = events[i].kind();
            los += (kind != END) as u32;
            his += (kind != START) as u32;
            i += 1;
        }
    }
    let mut found = Found::default();
    while i < to {
        let bits = events[i].pos_bits();
        let (mut run_los, mut run_his, mut run_planar) = (0u32, 0u32, 0u32);
        while i < events.len() && events[i].pos_bits() == bits {
            let kind = events[i].kind();
            run_los += (kind != END) as u32;
            run_his += (kind != START) as u32;
            run_planar += (kind == PLANAR) as u32;
            i += 1;
        }
        let p = events[i - 1].pos();
        if lo < p && p < hi {
            let counts = Counts {
                left: los,
                right: node.n - (his + run_his),
                planar: run_planar,
            };
            found.offer(candidates::price_with(&node.splits, p, node.owner, counts));
        }
        los += run_los;
        his += run_his;
    }
    found
}

/// [`sweep`] over a large segment in parallel: each chunk counts its events of each kind and
/// the runs starting in it inside the node, exclusive prefix sums over the chunks give each
/// chunk its counts-before, and the chunks sweep; the earlier chunk wins a tie.
fn sweep_chunks(events: &[Event], node: &Node) -> Found {
    let kinds: Vec<[u32; 3]> = events
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut kinds = [0u32; 3];
            for e in chunk {
                kinds[e.kind() as usize] += 1;
            }
            kinds
        })
        .collect();
    let mut before = Vec::with_capacity(kinds.len());
    let mut sum = [0u32; 3];
    for k in &kinds {
        before.push(sum);
        for a in 0..3 {
            sum[a] += k[a];
        }
    }
    (0..kinds.len())
        .into_par_iter()
        .map(|c| {
            let to = ((c + 1) * CHUNK).min(events.len());
            sweep(events, c * CHUNK, to, before[c], node)
        })
        .reduce(Found::default, Found::join)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::level::entries::ListEntry;
    use crate::geometry::Vec3;

    /// The chunked sweep of a large node finds the same best candidate (and count) as the
    /// serial one, with runs of equal positions crossing chunk boundaries.
    #[test]
    fn chunked_sweep_equals_serial_sweep() {
        let n = 3 * CHUNK as u32 + 77;
        let mut events: Vec<Event> = (0..n)
            .flat_map(|i| {
                let lo = (i / 7) as f32;
                let hi = if i % 5 == 0 { lo } else { lo + (i % 13) as f32 };
                let made = Event::make(lo, hi, i);
                made.into_iter().take(Event::count(lo, hi) as usize)
            })
            .collect();
        events.sort_by_key(|e| e.key());
        let bbox = Aabb::new(Vec3::splat(0.5), Vec3::splat(n as f32 / 7.0 - 3.0));
        let cost = CostModel::default();
        let node = Node {
            n,
            bbox: &bbox,
            axis: 1,
            owner: 0,
            splits: cost.splits_of(&bbox, 1),
        };
        let run = |parallel: bool| {
            let f = if parallel {
                sweep_chunks(&events, &node)
            } else {
                sweep(&events, 0, events.len(), [0; 3], &node)
            };
            let b = f.best.expect("a best candidate");
            (f.priced, b.split(1))
        };
        assert_eq!(run(true), run(false));
    }
}
