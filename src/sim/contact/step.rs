//! One step of a set of objects in contact, in named stages:
//!
//! 1. [`ContactWorld::sweep`]: every object's sample box at z_n and at its initial guess,
//!    grown by the largest sample displacement between them and its contact thickness;
//! 2. [`ContactWorld::group`]: two objects whose grown boxes meet, and which are in contact
//!    now (a pair of samples within their contact distance), join one island ([`Forest`]);
//!    objects that only come into contact within the step are left to stage 4; an object
//!    with self-contact whose own samples may touch is an island of one;
//! 3. [`ContactWorld::solve_groups`]: the islands in parallel ([`super::island`]), each
//!    stiffened and solved again while it ends deeper than the tolerance; the others step
//!    alone, exactly as without contact;
//! 4. [`ContactWorld::regroup`]: objects of different groups with a pair of samples that
//!    came within contact distance anywhere on their paths through the step (objects that
//!    met, or passed through each other) are undone and solved again as one island, until
//!    none are left;
//! 5. [`ContactWorld::stiffen`]: raised pair stiffnesses kept for later steps;
//! 6. [`ContactWorld::report`]: every object's step report and the step's contact figures.

use super::energy::{Body, ContactStats, PairContact};
use super::forest::Forest;
use super::island::step_island;
use super::pairs::{candidates, self_candidates};
use super::samples::ContactSamples;
use super::IslandSolver;
use crate::linalg3::{dot, norm, sub};
use crate::sim::elastic::Precision;
use crate::sim::object::SimSnapshot;
use crate::sim::{ReducedSim, StepReport};
use crate::Point3;
use rayon::prelude::*;

/// How many times a pair's penalty stiffness is multiplied when its island ends a step
/// deeper than the penetration tolerance: 4, which halves the depth under the same load
/// (pressure kappa delta^2).
pub const STIFFENING_FACTOR: f64 = 4.0;

/// Most stiffness raises (and so re-solves) of one island in one step: 4 raises allow 256x
/// the default stiffness, a sixteenth of the depth.
pub const MAX_STIFFENING: usize = 4;

/// The contact state of a set of objects (index i: object i throughout).
pub struct ContactWorld {
    samples: Vec<ContactSamples>,
    /// Friction coefficient of each object pair (row-major) and the smoothing velocity, m/s.
    pub(super) mu: Vec<f64>,
    pub(super) eps_v: f64,
    /// Penalty stiffness of each object pair (row-major), Pa/m^2; raised where a step went
    /// too deep.
    stiffness: Vec<f64>,
    /// The stiffnesses as given (before any raise), Pa/m^2: what the reverse pass's
    /// stiffness gradients are taken with respect to.
    pub(super) given_stiffness: Vec<f64>,
    tolerance: f64,
    pub(super) solver: IslandSolver,
    /// The arithmetic of the island members' elastic Hessian products.
    precision: Precision,
    /// Sample positions at the current state, per object.
    positions: Vec<Vec<Point3>>,
    /// Self-contact exclusion per object, metres (None: no self-contact).
    self_exclusion: Vec<Option<f64>>,
    /// Objects with self-contact whose own samples may touch within this step: solved as an
    /// island even when alone.
    self_near: Vec<bool>,
}

/// An object's swept box ([`ContactWorld::sweep`]) and the largest displacement of its
/// samples between z_n and the initial guess, metres.
struct Swept {
    lo: Point3,
    hi: Point3,
    moved: f64,
}

/// An island's final solve in a step, as the reverse pass needs it: its members (object
/// indices, in the order their coordinates were stacked) and the pair stiffnesses it used
/// where they differ from the given ones (raised in this step or an earlier one), so that a
/// recording keeps a few numbers per island and step, not a square of its members.
#[derive(Debug, Clone, PartialEq)]
pub struct IslandSolve {
    /// Object indices.
    pub members: Vec<usize>,
    /// (a, b, kappa): the stiffness of the pair of members (a, b) (indices into `members`),
    /// Pa/m^2, where it is not the given one.
    pub raised: Vec<(usize, usize, f64)>,
}

/// The result of stepping one group: each object's report, and for an island the contact
/// statistics with its deepest pair as object indices, and its final solve.
pub struct Solved {
    reports: Vec<(usize, StepReport)>,
    stats: Option<ContactStats>,
    island: Option<IslandSolve>,
    /// For an island: its objects and their pair stiffnesses (row-major over the group) if
    /// any was raised, and the number of raises.
    stiffened: Option<(Vec<usize>, Vec<f64>, usize)>,
}

/// What one contact step did.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactStepOutcome {
    /// Every object's step report, in object order.
    pub reports: Vec<StepReport>,
    /// Object pairs whose swept boxes met.
    pub object_pairs_near: usize,
    /// Active sample pairs at the end of the step, over every island.
    pub sample_pairs_active: usize,
    /// Deepest penetration, metres.
    pub penetration: f64,
    /// Deepest penetration as a fraction of the pair's smaller diagonal.
    pub penetration_fraction: f64,
    /// The pair (object indices) of that deepest fraction, if any island had contact.
    pub deepest_pair: Option<(usize, usize)>,
    /// Island sizes, largest first.
    pub islands: Vec<usize>,
    /// Objects undone and solved again in a merged island.
    pub regrouped: usize,
    /// Stiffness raises over every island.
    pub stiffened: usize,
    /// The islands' final solves (what the reverse pass of a recorded step solves again).
    pub island_solves: Vec<IslandSolve>,
}

fn bounds(x: &[Point3], grow: f64) -> (Point3, Point3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in x {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d] - grow);
            hi[d] = hi[d].max(p[d] + grow);
        }
    }
    (lo, hi)
}

fn meet(a: &(Point3, Point3), b: &(Point3, Point3)) -> bool {
    (0..3).all(|d| a.0[d] <= b.1[d] && b.0[d] <= a.1[d])
}

impl ContactWorld {
    /// The contact state of objects `sims` with contact samples `samples`, pair friction `mu`
    /// and stiffness `stiffness` (row-major, Pa/m^2), smoothing velocity `eps_v` (m/s),
    /// penetration tolerance `tolerance` (a fraction of the smaller diagonal), self-contact
    /// exclusions (metres, None: none), the island solver and the arithmetic of the island
    /// members' elastic Hessian products ([`super::ContactSettings::hessian_precision`]).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        sims: &[&ReducedSim],
        samples: Vec<ContactSamples>,
        mu: Vec<f64>,
        eps_v: f64,
        stiffness: Vec<f64>,
        tolerance: f64,
        self_exclusion: Vec<Option<f64>>,
        solver: IslandSolver,
        precision: Precision,
    ) -> ContactWorld {
        let positions = sims
            .iter()
            .zip(&samples)
            .map(|(s, c)| c.positions(s.layout(), s.z()))
            .collect();
        let n = sims.len();
        ContactWorld {
            samples,
            mu,
            eps_v,
            given_stiffness: stiffness.clone(),
            stiffness,
            tolerance,
            solver,
            precision,
            positions,
            self_exclusion,
            self_near: vec![false; n],
        }
    }

    /// The contact samples of object `i`.
    pub fn samples(&self, i: usize) -> &ContactSamples {
        &self.samples[i]
    }

    /// The sample positions of object `i` at its current state, metres.
    pub fn positions(&self, i: usize) -> &[Point3] {
        &self.positions[i]
    }

    /// The pair stiffnesses (row-major), Pa/m^2.
    pub fn stiffness(&self) -> &[f64] {
        &self.stiffness
    }

    /// One step of every object; `sims[i]` is object i.
    pub fn step(&mut self, sims: &mut [&mut ReducedSim]) -> ContactStepOutcome {
        let swept = self.sweep(sims);
        let (mut forest, near) = self.group(&swept);
        let snapshots: Vec<SimSnapshot> = sims.iter().map(|s| s.snapshot()).collect();
        let groups = forest.groups();
        let solved = self.solve_groups(&groups, sims);
        let (solved, regrouped) = self.regroup(&mut forest, groups, solved, sims, &snapshots);
        let stiffened = self.stiffen(&solved);
        let mut outcome = Self::report(solved, sims.len());
        outcome.object_pairs_near = near;
        outcome.regrouped = regrouped;
        outcome.stiffened = stiffened;
        outcome
    }

    /// Stage 1: every object's swept box, grown by the largest sample displacement between
    /// z_n and the initial guess (the solution may differ from the guess by as much) and the
    /// thickness.
    fn sweep(&self, sims: &[&mut ReducedSim]) -> Vec<Swept> {
        sims.par_iter()
            .zip(&self.samples)
            .zip(&self.positions)
            .map(|((sim, s), x0)| {
                let guess = s.positions(sim.layout(), &sim.begin_step().guess);
                let moved = x0
                    .iter()
                    .zip(&guess)
                    .map(|(a, b)| norm(&sub(a, b)))
                    .fold(0.0, f64::max);
                let grow = moved + s.thickness;
                let (lo0, hi0) = bounds(x0, grow);
                let (lo1, hi1) = bounds(&guess, grow);
                Swept {
                    lo: std::array::from_fn(|d| lo0[d].min(lo1[d])),
                    hi: std::array::from_fn(|d| hi0[d].max(hi1[d])),
                    moved,
                }
            })
            .collect()
    }

    /// Stage 2: the islands (and the number of object pairs whose boxes met), and which
    /// objects' own samples may touch within the step.
    fn group(&mut self, swept: &[Swept]) -> (Forest, usize) {
        let n = swept.len();
        let mut forest = Forest::new(n);
        let mut near = 0;
        for a in 0..n {
            for b in a + 1..n {
                let (sa, sb) = (&swept[a], &swept[b]);
                if meet(&(sa.lo, sa.hi), &(sb.lo, sb.hi)) {
                    near += 1;
                    // Only objects in contact now: joining those that could meet within
                    // the step (a margin of their moves) made islands of objects that never
                    // touched, which then paid the island's iterations; the ones that do
                    // meet are caught along their paths in stage 4 (docs/performance.md).
                    if self.in_contact(a, b) {
                        forest.union(a, b);
                    }
                }
            }
        }
        for (a, s) in swept.iter().enumerate() {
            // Two samples of one object move apart by at most twice its largest move.
            self.self_near[a] = self.self_within(a, 4.0 * s.moved);
        }
        (forest, near)
    }

    /// Stage 3: solve `groups` in parallel; `sims` are all the objects.
    fn solve_groups(&self, groups: &[Vec<usize>], sims: &mut [&mut ReducedSim]) -> Vec<Solved> {
        let mut slots: Vec<Option<&mut ReducedSim>> =
            sims.iter_mut().map(|s| Some(&mut **s)).collect();
        let work: Vec<(&Vec<usize>, Vec<&mut ReducedSim>)> = groups
            .iter()
            .map(|g| {
                let members = g
                    .iter()
                    .map(|&i| slots[i].take().expect("groups are disjoint"))
                    .collect();
                (g, members)
            })
            .collect();
        work.into_par_iter()
            .map(|(g, members)| self.solve(g, members))
            .collect()
    }

    /// Step one group: a single object alone (as without contact) unless its own samples may
    /// touch, several as an island, stiffened and solved again from where it ended while it
    /// ends deeper than the tolerance ([`MAX_STIFFENING`] times at most).
    fn solve(&self, group: &[usize], mut sims: Vec<&mut ReducedSim>) -> Solved {
        if let [only] = *group {
            if !self.self_near[only] {
                let rep = sims[0].step();
                return Solved {
                    reports: vec![(only, rep)],
                    stats: None,
                    island: None,
                    stiffened: None,
                };
            }
        }
        let bodies = {
            let shared: Vec<&ReducedSim> = sims.iter().map(|s| &**s).collect();
            self.bodies(group, &shared)
        };
        let m = group.len();
        let mut stiffness = self.over(group, &self.stiffness);
        let mu = self.over(group, &self.mu);
        let snapshots: Vec<_> = sims.iter().map(|s| s.snapshot()).collect();
        let mut raises = 0;
        let mut start: Option<Vec<f64>> = None;
        // Wall time of the solves undone for a stiffer one: each member's report counts it.
        let mut undone_s = vec![0.0; m];
        loop {
            let contact = PairContact::new(bodies.clone(), stiffness.clone());
            let (reports, mut stats) = step_island(
                &mut sims,
                &contact,
                &mu,
                self.eps_v,
                self.solver,
                self.precision,
                start.as_deref(),
            );
            if stats.deepest_fraction > self.tolerance && raises < MAX_STIFFENING {
                // Too deep: undo, stiffen every pair of objects that went too deep (in a
                // large island several do at once; one at a time used up the raises on
                // the first few), solve again from where this solve ended (the stiffer pairs
                // only have to push out what went too deep).
                let end: Vec<f64> = sims.iter().flat_map(|s| s.z().iter().copied()).collect();
                for (a, b) in contact.pairs_deeper_than(&end, self.tolerance) {
                    stiffness[a * m + b] *= STIFFENING_FACTOR;
                    if a != b {
                        stiffness[b * m + a] *= STIFFENING_FACTOR;
                    }
                }
                start = Some(end);
                for (s, snap) in sims.iter_mut().zip(&snapshots) {
                    s.restore(snap);
                }
                for (spent, r) in undone_s.iter_mut().zip(&reports) {
                    *spent += r.wall_s;
                }
                raises += 1;
                continue;
            }
            stats.deepest_pair = stats.deepest_pair.map(|(a, b)| (group[a], group[b]));
            let reports = reports.into_iter().zip(&undone_s).map(|(mut r, spent)| {
                r.wall_s += spent;
                r
            });
            return Solved {
                reports: group.iter().copied().zip(reports).collect(),
                stats: Some(stats),
                island: Some(self.island_solve(group, &stiffness)),
                stiffened: (raises > 0).then(|| (group.to_vec(), stiffness, raises)),
            };
        }
    }

    /// Stage 4: while objects of different groups met on their paths through the step (or an
    /// object that stepped alone ended touching itself), undo the groups that merge and solve
    /// them again; the final solves and the number of objects undone.
    fn regroup(
        &mut self,
        forest: &mut Forest,
        mut current: Vec<Vec<usize>>,
        solved: Vec<Solved>,
        sims: &mut [&mut ReducedSim],
        snapshots: &[SimSnapshot],
    ) -> (Vec<Solved>, usize) {
        let n = sims.len();
        let mut solved: Vec<Option<Solved>> = solved.into_iter().map(Some).collect();
        let mut regrouped = 0;
        // Wall time of the solves undone by a regrouping, per object: counted in its report.
        let mut undone_s = vec![0.0; n];
        // The sample positions at z_n: each sample's path in the step is the segment from
        // there to where it ended (positions are linear in z).
        let start = std::mem::take(&mut self.positions);
        loop {
            self.positions = sims
                .par_iter()
                .zip(&self.samples)
                .map(|(s, c)| c.positions(s.layout(), s.z()))
                .collect();
            let mut group_of = vec![0; n];
            for (g, members) in current.iter().enumerate() {
                for &i in members {
                    group_of[i] = g;
                }
            }
            let mut merged = false;
            for a in 0..n {
                for b in a + 1..n {
                    if forest.joined(a, b) || group_of[a] == group_of[b] {
                        continue;
                    }
                    if self.met_on_the_way(a, b, &start) {
                        forest.union(a, b);
                        merged = true;
                    }
                }
            }
            // Objects that stepped alone but ended touching themselves: again, as islands.
            let self_redo: Vec<usize> = (0..n)
                .filter(|&a| !self.self_near[a] && self.self_within(a, 0.0))
                .collect();
            if !merged && self_redo.is_empty() {
                let mut solved: Vec<Solved> = solved.into_iter().flatten().collect();
                for (i, r) in solved.iter_mut().flat_map(|s| s.reports.iter_mut()) {
                    r.wall_s += undone_s[*i];
                }
                return (solved, regrouped);
            }
            for &a in &self_redo {
                self.self_near[a] = true;
            }
            let next = forest.groups();
            let mut keep = Vec::new();
            let mut redo = Vec::new();
            for g in next {
                match current.iter().position(|c| *c == g) {
                    Some(k) if !(g.len() == 1 && self_redo.contains(&g[0])) => {
                        keep.push((g, solved[k].take()))
                    }
                    _ => redo.push(g),
                }
            }
            for g in &redo {
                for &i in g {
                    sims[i].restore(&snapshots[i]);
                    regrouped += 1;
                }
            }
            // The solves of the groups not kept are undone: keep their time.
            for (i, r) in solved.iter().flatten().flat_map(|s| s.reports.iter()) {
                undone_s[*i] += r.wall_s;
            }
            let fresh = self.solve_groups(&redo, sims);
            current = keep.iter().map(|(g, _)| g.clone()).collect();
            solved = keep.into_iter().map(|(_, s)| s).collect();
            current.extend(redo);
            solved.extend(fresh.into_iter().map(Some));
        }
    }

    /// Stage 5: keep the raised stiffnesses of the islands that went too deep; the number of
    /// raises.
    fn stiffen(&mut self, solved: &[Solved]) -> usize {
        let n = self.samples.len();
        let mut raises = 0;
        for (group, k, r) in solved.iter().filter_map(|s| s.stiffened.as_ref()) {
            raises += r;
            let m = group.len();
            for (p, &a) in group.iter().enumerate() {
                for (q, &b) in group.iter().enumerate() {
                    self.stiffness[a * n + b] = k[p * m + q];
                }
            }
        }
        raises
    }

    /// Stage 6: every object's report in object order and the islands' contact figures.
    fn report(solved: Vec<Solved>, n: usize) -> ContactStepOutcome {
        let mut reports: Vec<Option<StepReport>> = vec![None; n];
        let mut out = ContactStepOutcome {
            reports: Vec::new(),
            object_pairs_near: 0,
            sample_pairs_active: 0,
            penetration: 0.0,
            penetration_fraction: 0.0,
            deepest_pair: None,
            islands: Vec::new(),
            regrouped: 0,
            stiffened: 0,
            island_solves: Vec::new(),
        };
        for s in solved {
            out.island_solves.extend(s.island);
            if let Some(st) = s.stats {
                out.islands.push(s.reports.len());
                out.sample_pairs_active += st.active;
                out.penetration = out.penetration.max(st.deepest);
                if st.deepest_fraction > out.penetration_fraction {
                    out.penetration_fraction = st.deepest_fraction;
                    out.deepest_pair = st.deepest_pair;
                }
            }
            for (i, r) in s.reports {
                reports[i] = Some(r);
            }
        }
        out.islands.sort_unstable_by(|a, b| b.cmp(a));
        out.reports = reports
            .into_iter()
            .map(|r| r.expect("every object is in one group"))
            .collect();
        out
    }

    /// The bodies of the island `group` (object indices; `sims` its members in that order),
    /// stacked in that order.
    pub(super) fn bodies<'s>(&'s self, group: &[usize], sims: &[&ReducedSim]) -> Vec<Body<'s>> {
        let mut offset = 0;
        group
            .iter()
            .zip(sims)
            .map(|(&i, s)| {
                let body = Body {
                    samples: &self.samples[i],
                    layout: s.layout(),
                    offset,
                    diagonal: s.diagonal(),
                    self_exclusion: self.self_exclusion[i],
                };
                offset += body.layout.dofs();
                body
            })
            .collect()
    }

    /// The record of the island `group` solved with the pair stiffnesses `stiffness`
    /// (row-major over its members).
    fn island_solve(&self, group: &[usize], stiffness: &[f64]) -> IslandSolve {
        let m = group.len();
        let given = self.over(group, &self.given_stiffness);
        let raised = (0..m * m)
            .filter(|&k| stiffness[k] != given[k])
            .map(|k| (k / m, k % m, stiffness[k]))
            .collect();
        IslandSolve {
            members: group.to_vec(),
            raised,
        }
    }

    /// The pair stiffnesses (row-major over its members, Pa/m^2) the island `solve` used.
    pub(super) fn island_stiffness(&self, solve: &IslandSolve) -> Vec<f64> {
        let m = solve.members.len();
        let mut k = self.over(&solve.members, &self.given_stiffness);
        for &(a, b, v) in &solve.raised {
            k[a * m + b] = v;
        }
        k
    }

    /// The entries of the row-major object-pair matrix `full` between the members of
    /// `group`, row-major over them.
    pub(super) fn over(&self, group: &[usize], full: &[f64]) -> Vec<f64> {
        let n = self.samples.len();
        group
            .iter()
            .flat_map(|&a| group.iter().map(move |&b| full[a * n + b]))
            .collect()
    }

    /// Whether object `a` has self-contact and a pair of its own samples (far apart at rest)
    /// within contact distance plus `margin` (metres) now.
    fn self_within(&self, a: usize, margin: f64) -> bool {
        let Some(ex) = self.self_exclusion[a] else {
            return false;
        };
        let s = &self.samples[a];
        !self_candidates(
            a,
            &self.positions[a],
            &s.rest,
            2.0 * s.thickness + margin,
            ex,
        )
        .is_empty()
    }

    /// Whether a sample of object `a` and one of object `b` came within contact distance of
    /// each other anywhere on their paths from `start` (positions at z_n, per object) to
    /// their positions now, both moving along straight segments over the same step fraction
    /// (sample positions are linear in z, and a solve of each group moves its objects from
    /// z_n to z_{n+1}; the segment is the straight path between them). Objects that ended
    /// apart but passed through each other on the way are caught too.
    fn met_on_the_way(&self, a: usize, b: usize, start: &[Vec<Point3>]) -> bool {
        let d = self.samples[a].thickness + self.samples[b].thickness;
        let moved = |o: usize| {
            start[o]
                .iter()
                .zip(&self.positions[o])
                .map(|(p, q)| norm(&sub(p, q)))
                .fold(0.0, f64::max)
        };
        let reach = d + moved(a) + moved(b);
        let pair = [start[a].as_slice(), start[b].as_slice()];
        let (cands, _) = candidates(&pair, &|_, _| reach);
        cands.iter().any(|c| {
            let (p0, q0) = (start[a][c.i], start[b][c.j]);
            let (p1, q1) = (self.positions[a][c.i], self.positions[b][c.j]);
            // Relative position p0 - q0 + s w, s in [0, 1]: its closest approach.
            let r = sub(&p0, &q0);
            let w = sub(&sub(&p1, &p0), &sub(&q1, &q0));
            let ww = dot(&w, &w);
            let s = if ww > 0.0 {
                (-dot(&r, &w) / ww).clamp(0.0, 1.0)
            } else {
                0.0
            };
            norm(&std::array::from_fn(|k| r[k] + s * w[k])) <= d
        })
    }

    /// Whether objects `a` and `b` are in contact now: a pair of their samples within
    /// contact distance.
    fn in_contact(&self, a: usize, b: usize) -> bool {
        let d = self.samples[a].thickness + self.samples[b].thickness;
        if !meet(
            &bounds(&self.positions[a], d),
            &bounds(&self.positions[b], 0.0),
        ) {
            return false;
        }
        let pair = [self.positions[a].as_slice(), self.positions[b].as_slice()];
        !candidates(&pair, &|_, _| d).0.is_empty()
    }
}
