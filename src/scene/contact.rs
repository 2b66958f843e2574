//! Object-object contact in a [`super::World`] (scenes with `[contact]`): each object's
//! contact samples, the grouping of objects into islands each step, the islands solved in
//! parallel, and the contact report.
//!
//! A step: every object's sample box at z_n and at its initial guess, grown by the largest
//! sample displacement between them and its contact thickness; two objects whose grown boxes
//! meet, and which have a pair of samples within their contact distance plus twice their
//! displacements now, join one island (union-find), solved together
//! ([`crate::sim::contact::island`]); the others step alone, exactly as without contact.
//! After the solves, any two objects of different islands whose samples ended within
//! contact distance (the bound was too tight: a collider or a pile pushed harder than the
//! guess) are undone and solved again as one island, until none are left.
//!
//! Self-contact (`self_contact`): an object whose own samples, far apart at rest, come within
//! reach in a step is solved as an island of one (or within its island), with the same pair
//! energy between its own samples; one whose samples stay apart steps alone as before.

use super::object::SceneObject;
use super::report::{ContactStepRow, ContactSummary};
use crate::geometry::Shape;
use crate::report::Stopwatch;
use crate::sim::contact::island::step_island;
use crate::sim::contact::pairs::{candidates, self_candidates};
use crate::sim::contact::samples::default_count;
use crate::sim::contact::{
    Body, ContactSamples, ContactSettings, ContactStats, IslandSolver, PairContact,
};
use crate::sim::motion::rotation_matrix;
use crate::sim::StepReport;
use crate::{Error, Point3, Result};
use rayon::prelude::*;

/// How many times a pair's penalty stiffness is multiplied when its island ends a step
/// deeper than the penetration tolerance: 4, which halves the depth under the same load
/// (pressure kappa delta^2).
pub const STIFFENING_FACTOR: f64 = 4.0;

/// Most stiffness raises (and so re-solves) of one island in one step: 4 raises allow 256x
/// the default stiffness, a sixteenth of the depth.
pub const MAX_STIFFENING: usize = 4;

/// The contact state of a world.
pub(super) struct WorldContact {
    samples: Vec<ContactSamples>,
    /// Friction coefficient of each object pair (row-major) and the smoothing velocity, m/s.
    mu: Vec<f64>,
    eps_v: f64,
    stiffness: Vec<f64>,
    tolerance: f64,
    solver: IslandSolver,
    /// Sample positions at the current state, per object.
    positions: Vec<Vec<Point3>>,
    /// Self-contact exclusion per object, metres (None: no self-contact).
    self_exclusion: Vec<Option<f64>>,
    /// Objects with self-contact whose own samples may touch within this step: solved as an
    /// island even when alone.
    self_near: Vec<bool>,
    warned: std::collections::BTreeSet<(usize, usize)>,
    pub(super) summary: ContactSummary,
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

fn find(parent: &mut [usize], i: usize) -> usize {
    let mut r = i;
    while parent[r] != r {
        r = parent[r];
    }
    let mut i = i;
    while parent[i] != r {
        let next = parent[i];
        parent[i] = r;
        i = next;
    }
    r
}

fn union(parent: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb)] = ra.min(rb);
    }
}

/// Groups of a union-find forest, each sorted, ordered by their first object.
fn groups(parent: &mut [usize]) -> Vec<Vec<usize>> {
    let n = parent.len();
    let mut by_root: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for i in 0..n {
        let r = find(parent, i);
        by_root.entry(r).or_default().push(i);
    }
    by_root.into_values().collect()
}

/// The result of stepping one group: each object's report, and for an island the contact
/// statistics with its deepest pair as object indices.
struct Solved {
    reports: Vec<(usize, StepReport)>,
    stats: Option<ContactStats>,
    /// For an island: its objects and their pair stiffnesses (row-major over the group) if
    /// any was raised, and the number of raises.
    stiffened: Option<(Vec<usize>, Vec<f64>, usize)>,
}

impl WorldContact {
    /// Contact samples for every object (`shapes[i]` None: a prepared object, refused), the
    /// pair stiffnesses, and the check that no two objects start interpenetrating.
    pub(super) fn new(
        settings: &ContactSettings,
        objects: &mut [SceneObject],
        shapes: &[Option<Shape>],
        colliders: &[crate::sim::Collider],
    ) -> Result<WorldContact> {
        settings.validate()?;
        // Collider friction lives in each object's own step.
        for (index, o) in objects.iter_mut().enumerate() {
            let mu: Vec<f64> = colliders
                .iter()
                .map(|c| settings.friction_between(Some(o.name()), c.name.as_deref()))
                .collect();
            let name = o.name().to_string();
            o.sim_mut()
                .set_collider_friction(&mu, settings.friction_velocity)
                .map_err(|e| Error::Object {
                    index,
                    name,
                    source: Box::new(e),
                })?;
        }
        let objects: &[SceneObject] = objects;
        let mut samples = Vec::with_capacity(objects.len());
        for (index, (o, shape)) in objects.iter().zip(shapes).enumerate() {
            let ctx = |e: Error| Error::Object {
                index,
                name: o.name().to_string(),
                source: Box::new(e),
            };
            let shape = shape.as_ref().ok_or_else(|| {
                ctx(Error::Scene {
                    message: "object-object contact needs the object's shape for its contact \
                              samples; an object made from arrays (World::with_objects) has \
                              none"
                        .into(),
                })
            })?;
            let count = o
                .spec()
                .contact_samples
                .or(settings.samples)
                .unwrap_or_else(|| default_count(shape, settings.radius));
            samples
                .push(ContactSamples::new(shape, o.basis(), count, settings.radius).map_err(ctx)?);
        }
        let n = objects.len();
        let stiffness: Vec<f64> = (0..n * n)
            .map(|k| {
                let (a, b) = (k / n, k % n);
                settings.stiffness.unwrap_or_else(|| {
                    objects[a]
                        .sim()
                        .default_penalty()
                        .max(objects[b].sim().default_penalty())
                })
            })
            .collect();
        let names: Vec<&str> = objects.iter().map(|o| o.name()).collect();
        for p in &settings.pairs {
            for name in &p.between {
                if !names.contains(&name.as_str())
                    && !colliders.iter().any(|c| c.name.as_deref() == Some(name))
                {
                    return Err(Error::param(
                        "contact.pair.between",
                        format!("'{name}'"),
                        "names no object and no collider of the scene",
                    ));
                }
            }
        }
        let mu = (0..n * n)
            .map(|k| settings.friction_between(Some(names[k / n]), Some(names[k % n])))
            .collect();
        let positions: Vec<Vec<Point3>> = objects
            .iter()
            .zip(&samples)
            .map(|(o, s)| s.positions(o.sim().layout(), o.sim().z()))
            .collect();
        let self_exclusion: Vec<Option<f64>> = objects
            .iter()
            .zip(&samples)
            .map(|(o, s)| {
                o.spec()
                    .self_contact
                    .unwrap_or(settings.self_contact)
                    .then_some(settings.self_exclusion * 2.0 * s.thickness)
            })
            .collect();
        let contact = WorldContact {
            summary: ContactSummary {
                penetration_tolerance: settings.penetration_tolerance,
                samples: samples.iter().map(ContactSamples::len).collect(),
                thickness: samples.iter().map(|s| s.thickness).collect(),
                self_contact: self_exclusion.iter().map(Option::is_some).collect(),
                stiffness: stiffness.clone(),
                worst_penetration: 0.0,
                worst_penetration_fraction: 0.0,
                steps_over_tolerance: 0,
                step_ms_mean: 0.0,
                steps: Vec::new(),
            },
            samples,
            mu,
            eps_v: settings.friction_velocity,
            stiffness,
            tolerance: settings.penetration_tolerance,
            solver: settings.solver,
            positions,
            self_near: vec![false; n],
            self_exclusion,
            warned: Default::default(),
        };
        contact.check_start(objects, shapes)?;
        Ok(contact)
    }

    /// Refuse objects that start interpenetrating: a sample of one inside the other's
    /// placed shape, or two samples overlapping by more than the tolerance.
    fn check_start(&self, objects: &[SceneObject], shapes: &[Option<Shape>]) -> Result<()> {
        let n = objects.len();
        for a in 0..n {
            for b in 0..n {
                if a == b {
                    continue;
                }
                let (oa, ob) = (&objects[a], &objects[b]);
                let d = self.samples[a].thickness + self.samples[b].thickness;
                let pair = [self.positions[a].clone(), self.positions[b].clone()];
                let (cands, _) = candidates(&pair, &|_, _| d);
                let diag = oa.sim().diagonal().min(ob.sim().diagonal());
                let fail = |what: String| Error::Scene {
                    message: format!(
                        "objects '{}' and '{}' start interpenetrating: {what}; move them apart \
                         (placement.translation)",
                        oa.name(),
                        ob.name()
                    ),
                };
                if let Some(c) = cands.iter().find(|c| {
                    let (p, q) = (pair[0][c.i], pair[1][c.j]);
                    let r = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
                    d - r > self.tolerance * diag
                }) {
                    let p = pair[0][c.i];
                    return Err(fail(format!(
                        "their surfaces overlap at ({:.4}, {:.4}, {:.4}) m by more than the \
                         penetration tolerance ({} of the smaller diagonal, {:.3e} m)",
                        p[0],
                        p[1],
                        p[2],
                        self.tolerance,
                        self.tolerance * diag
                    )));
                }
                // A sample of a inside b's placed shape (deep inside, no sample of b near).
                let Some(shape) = &shapes[b] else { continue };
                let pl = &ob.spec().placement;
                let r = match &pl.rotation {
                    Some(aa) => {
                        let len = aa.axis.iter().map(|v| v * v).sum::<f64>().sqrt();
                        rotation_matrix(&aa.axis.map(|v| v / len), aa.degrees.to_radians())
                    }
                    None => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                };
                let local: Vec<Point3> = self.positions[a]
                    .iter()
                    .map(|x| {
                        let y: [f64; 3] = std::array::from_fn(|k| x[k] - pl.translation[k]);
                        std::array::from_fn(|k| (0..3).map(|m| r[m][k] * y[m]).sum())
                    })
                    .collect();
                if let Some(inside) = shape.contains(&local) {
                    if let Some(i) = inside.iter().position(|&v| v) {
                        let p = self.positions[a][i];
                        return Err(fail(format!(
                            "a surface point of '{}' at ({:.4}, {:.4}, {:.4}) m is inside '{}'",
                            oa.name(),
                            p[0],
                            p[1],
                            p[2],
                            ob.name()
                        )));
                    }
                }
            }
        }
        Ok(())
    }

    /// Step one group: a single object alone (as without contact) unless its own samples may
    /// touch, several as an island.
    fn solve(&self, group: &[usize], objs: Vec<&mut SceneObject>) -> Solved {
        if let [only] = *group {
            if !self.self_near[only] {
                let mut objs = objs;
                let rep = objs[0].sim_mut().step();
                return Solved {
                    reports: vec![(only, rep)],
                    stats: None,
                    stiffened: None,
                };
            }
        }
        let mut offset = 0;
        let bodies: Vec<Body> = group
            .iter()
            .zip(&objs)
            .map(|(&i, o)| {
                let body = Body {
                    samples: &self.samples[i],
                    layout: o.sim().layout(),
                    offset,
                    diagonal: o.sim().diagonal(),
                    self_exclusion: self.self_exclusion[i],
                };
                offset += body.layout.dofs();
                body
            })
            .collect();
        let n = self.samples.len();
        let m = group.len();
        let mut stiffness: Vec<f64> = group
            .iter()
            .flat_map(|&a| group.iter().map(move |&b| self.stiffness[a * n + b]))
            .collect();
        let mu: Vec<f64> = group
            .iter()
            .flat_map(|&a| group.iter().map(move |&b| self.mu[a * n + b]))
            .collect();
        let mut sims: Vec<&mut crate::sim::ReducedSim> =
            objs.into_iter().map(|o| o.sim_mut()).collect();
        let snapshots: Vec<_> = sims.iter().map(|s| s.snapshot()).collect();
        let mut raises = 0;
        let mut start: Option<Vec<f64>> = None;
        loop {
            let contact = PairContact::new(bodies.clone(), stiffness.clone());
            let (reports, mut stats) = step_island(
                &mut sims,
                &contact,
                &mu,
                self.eps_v,
                self.solver,
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
                raises += 1;
                continue;
            }
            stats.deepest_pair = stats.deepest_pair.map(|(a, b)| (group[a], group[b]));
            return Solved {
                reports: group.iter().copied().zip(reports).collect(),
                stats: Some(stats),
                stiffened: (raises > 0).then(|| (group.to_vec(), stiffness, raises)),
            };
        }
    }

    /// Solve `groups` in parallel; `objects` are all the world's objects.
    fn solve_groups(&self, groups: &[Vec<usize>], objects: &mut [SceneObject]) -> Vec<Solved> {
        let mut slots: Vec<Option<&mut SceneObject>> = objects.iter_mut().map(Some).collect();
        let work: Vec<(&Vec<usize>, Vec<&mut SceneObject>)> = groups
            .iter()
            .map(|g| {
                let objs = g
                    .iter()
                    .map(|&i| slots[i].take().expect("groups are disjoint"))
                    .collect();
                (g, objs)
            })
            .collect();
        work.into_par_iter()
            .map(|(g, objs)| self.solve(g, objs))
            .collect()
    }

    /// One world step with contact; every object's report, in object order.
    pub(super) fn step(
        &mut self,
        objects: &mut [SceneObject],
        warnings: &mut Vec<String>,
    ) -> Vec<StepReport> {
        let sw = Stopwatch::start();
        let n = objects.len();
        // Swept boxes: the samples' box at z_n and at the initial guess, grown by the largest
        // sample displacement between them (the solution may differ from the guess by as
        // much) and the thickness.
        let swept: Vec<((Point3, Point3), f64)> = objects
            .par_iter()
            .zip(&self.samples)
            .zip(&self.positions)
            .map(|((o, s), x0)| {
                let sim = o.sim();
                let guess = s.positions(sim.layout(), &sim.begin_step().guess);
                let moved = x0
                    .iter()
                    .zip(&guess)
                    .map(|(a, b)| {
                        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
                            .sqrt()
                    })
                    .fold(0.0, f64::max);
                let grow = moved + s.thickness;
                let (lo0, hi0) = bounds(x0, grow);
                let (lo1, hi1) = bounds(&guess, grow);
                (
                    (
                        std::array::from_fn(|d| lo0[d].min(lo1[d])),
                        std::array::from_fn(|d| hi0[d].max(hi1[d])),
                    ),
                    moved,
                )
            })
            .collect();
        let mut parent: Vec<usize> = (0..n).collect();
        let mut near = 0;
        for a in 0..n {
            for b in a + 1..n {
                let ((box_a, moved_a), (box_b, moved_b)) = (&swept[a], &swept[b]);
                if meet(box_a, box_b) {
                    near += 1;
                    // Boxes are loose for rotated and round objects: join the two only if
                    // some pair of their samples now is within reach (the same margin).
                    if self.within(a, b, 2.0 * (moved_a + moved_b)) {
                        union(&mut parent, a, b);
                    }
                }
            }
        }
        for (a, (_, moved)) in swept.iter().enumerate() {
            // Two samples of one object move apart by at most twice its largest move.
            self.self_near[a] = self.self_within(a, 4.0 * moved);
        }
        let snapshots: Vec<_> = objects.iter().map(|o| o.sim().snapshot()).collect();
        let mut current = groups(&mut parent);
        let mut solved: Vec<Option<Solved>> = self
            .solve_groups(&current, objects)
            .into_iter()
            .map(Some)
            .collect();
        let mut regrouped = 0;
        loop {
            self.positions = objects
                .par_iter()
                .zip(&self.samples)
                .map(|(o, s)| s.positions(o.sim().layout(), o.sim().z()))
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
                    let (ga, gb) = (group_of[a], group_of[b]);
                    if find(&mut parent, a) == find(&mut parent, b) || ga == gb {
                        continue;
                    }
                    if self.touching(a, b) {
                        union(&mut parent, a, b);
                        merged = true;
                    }
                }
            }
            // Objects that stepped alone but ended touching themselves: again, as islands.
            let self_redo: Vec<usize> = (0..n)
                .filter(|&a| !self.self_near[a] && self.self_within(a, 0.0))
                .collect();
            if !merged && self_redo.is_empty() {
                break;
            }
            for &a in &self_redo {
                self.self_near[a] = true;
            }
            // Undo the groups that merged and solve the merged ones again.
            let next = groups(&mut parent);
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
                    objects[i].sim_mut().restore(&snapshots[i]);
                    regrouped += 1;
                }
            }
            let fresh = self.solve_groups(&redo, objects);
            current = keep.iter().map(|(g, _)| g.clone()).collect();
            solved = keep.into_iter().map(|(_, s)| s).collect();
            current.extend(redo);
            solved.extend(fresh.into_iter().map(Some));
        }
        let mut reports: Vec<Option<StepReport>> = vec![None; n];
        let mut row = ContactStepRow {
            step: 0,
            wall_ms: 0.0,
            object_pairs_tested: n * (n.saturating_sub(1)) / 2,
            object_pairs_near: near,
            sample_pairs_active: 0,
            penetration: 0.0,
            penetration_fraction: 0.0,
            islands: Vec::new(),
            regrouped,
            stiffened: 0,
        };
        let mut deepest_pair = None;
        for s in solved.into_iter().flatten() {
            if let Some((group, k, raises)) = s.stiffened {
                row.stiffened += raises;
                let m = group.len();
                for (p, &a) in group.iter().enumerate() {
                    for (q, &b) in group.iter().enumerate() {
                        self.stiffness[a * n + b] = k[p * m + q];
                    }
                }
                self.summary.stiffness.clone_from(&self.stiffness);
            }
            if let Some(st) = s.stats {
                row.islands.push(s.reports.len());
                row.sample_pairs_active += st.active;
                row.penetration = row.penetration.max(st.deepest);
                if st.deepest_fraction > row.penetration_fraction {
                    row.penetration_fraction = st.deepest_fraction;
                    deepest_pair = st.deepest_pair;
                }
            }
            for (i, r) in s.reports {
                reports[i] = Some(r);
            }
        }
        row.islands.sort_unstable_by(|a, b| b.cmp(a));
        let reports: Vec<StepReport> = reports
            .into_iter()
            .zip(objects.iter_mut())
            .map(|(r, o)| o.record(r.expect("every object is in one group"), warnings))
            .collect();
        row.step = reports.first().map_or(0, |r| r.step);
        if row.penetration_fraction > self.tolerance {
            self.summary.steps_over_tolerance += 1;
            if let Some((a, b)) = deepest_pair {
                if a == b && self.warned.insert((a, b)) {
                    warnings.push(format!(
                        "object '{}': step {}: self-penetration {:.3e} m, {:.2}% of its \
                         diagonal, above the tolerance ({:.2}%); raise contact.stiffness or \
                         shorten the time step",
                        objects[a].name(),
                        row.step,
                        row.penetration,
                        100.0 * row.penetration_fraction,
                        100.0 * self.tolerance
                    ));
                } else if self.warned.insert((a, b)) {
                    warnings.push(format!(
                        "objects '{}' and '{}': step {}: penetration {:.3e} m, {:.2}% of the \
                         smaller diagonal, above the tolerance ({:.2}%); raise \
                         contact.stiffness or shorten the time step",
                        objects[a].name(),
                        objects[b].name(),
                        row.step,
                        row.penetration,
                        100.0 * row.penetration_fraction,
                        100.0 * self.tolerance
                    ));
                }
            }
        }
        let s = &mut self.summary;
        s.worst_penetration = s.worst_penetration.max(row.penetration);
        s.worst_penetration_fraction = s.worst_penetration_fraction.max(row.penetration_fraction);
        row.wall_ms = sw.elapsed() * 1e3;
        let k = s.steps.len() as f64;
        s.step_ms_mean = (s.step_ms_mean * k + row.wall_ms) / (k + 1.0);
        s.steps.push(row);
        reports
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

    /// Whether objects `a` and `b` have samples within contact distance now.
    fn touching(&self, a: usize, b: usize) -> bool {
        self.within(a, b, 0.0)
    }

    /// Whether objects `a` and `b` have samples within contact distance plus `margin`
    /// (metres) now.
    fn within(&self, a: usize, b: usize, margin: f64) -> bool {
        let d = self.samples[a].thickness + self.samples[b].thickness + margin;
        if !meet(
            &bounds(&self.positions[a], d),
            &bounds(&self.positions[b], 0.0),
        ) {
            return false;
        }
        let pair = [self.positions[a].clone(), self.positions[b].clone()];
        !candidates(&pair, &|_, _| d).0.is_empty()
    }
}
