//! Object-object contact in a [`super::World`] (scenes with `[contact]`): the adaptor between
//! the world's objects and [`crate::sim::contact::step::ContactWorld`], which steps them in
//! stages. Here: each object's contact samples and friction from the scene, the check that no
//! two objects start interpenetrating, and each step's reports, warnings and contact row.

use super::object::SceneObject;
use super::report::{ContactStepRow, ContactSummary, VisibleSpot};
use crate::geometry::{Aabb, Shape};
use crate::report::{Stopwatch, Warning};
use crate::sim::contact::pairs::candidates;
use crate::sim::contact::samples::default_count;
use crate::sim::contact::step::{ContactWorld, IslandSolve};
use crate::sim::contact::surface::derived_surface;
use crate::sim::contact::visible::{deepest_visible, SurfacePoints};
use crate::sim::contact::{ContactSamples, ContactSettings};
use crate::sim::motion::rotation_matrix;
use crate::sim::{ReducedSim, StepReport};
use crate::{Error, Point3, Result};

/// The contact state of a world.
pub(super) struct WorldContact {
    world: ContactWorld,
    /// Each object's own surface points, for the visible penetration (None: not covered).
    surface: Vec<Option<SurfacePoints>>,
    tolerance: f64,
    warned: std::collections::BTreeSet<(usize, usize)>,
    pub(super) summary: ContactSummary,
    /// The islands' final solves of the last step (what a recording keeps).
    pub(super) last_islands: Vec<IslandSolve>,
}

impl WorldContact {
    /// Contact samples for every object (`shapes[i]` None: a prepared object, refused; a
    /// point cloud or image: on its derived surface, added to the object's render sets), the
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
        // Point clouds, splats and images have no surface of their own: their samples are
        // spread over the surface of the volume they occupy, drawn beside their frames.
        let mut derived: Vec<Option<Shape>> = Vec::with_capacity(objects.len());
        let mut surface_triangles = Vec::with_capacity(objects.len());
        for (index, (o, shape)) in objects.iter_mut().zip(shapes).enumerate() {
            let name = o.name().to_string();
            let ctx = |e: Error| Error::Object {
                index,
                name: name.clone(),
                source: Box::new(e),
            };
            let mesh = match shape {
                Some(s) => derived_surface(s).map_err(ctx)?,
                None => None,
            };
            surface_triangles.push(mesh.as_ref().map(|m| m.triangles().len()));
            if let Some(m) = &mesh {
                o.add_contact_surface(m).map_err(ctx)?;
            }
            derived.push(mesh.map(Shape::Mesh));
        }
        let shapes: Vec<Option<&Shape>> = derived
            .iter()
            .zip(shapes)
            .map(|(d, s)| d.as_ref().or(s.as_ref()))
            .collect();
        let objects: &[SceneObject] = objects;
        // Each object's sample count (None without a shape, refused below), checked for
        // memory all together before any sample is made.
        let counts: Vec<Option<usize>> = objects
            .iter()
            .zip(&shapes)
            .map(|(o, shape)| shape.map(|s| sample_count(o, s, settings)))
            .collect();
        check_sample_memory(objects, &counts)?;
        let mut samples = Vec::with_capacity(objects.len());
        for (index, (o, shape)) in objects.iter().zip(&shapes).enumerate() {
            let ctx = |e: Error| Error::Object {
                index,
                name: o.name().to_string(),
                source: Box::new(e),
            };
            let shape = shape.ok_or_else(|| {
                ctx(Error::Scene {
                    message: "object-object contact needs the object's shape for its contact \
                              samples; an object made from arrays (World::with_objects) has \
                              none"
                        .into(),
                })
            })?;
            let count = counts[index].unwrap_or_default();
            samples.push(
                ContactSamples::new(shape, o.basis(), count, settings.radius)
                    .and_then(|s| s.with_features(shape, o.basis(), settings.feature_spacing))
                    .map_err(ctx)?,
            );
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
        // Points on each object's own surface about a sample spacing apart, edges and
        // corners included (a surface the kernels do not cover is left unmeasured).
        let surface: Vec<Option<SurfacePoints>> = objects
            .iter()
            .zip(&shapes)
            .zip(&samples)
            .map(|((o, shape), s)| {
                shape.and_then(|sh| SurfacePoints::new(sh, o.basis(), s.spacing()).ok())
            })
            .collect();
        let summary = ContactSummary {
            penetration_tolerance: settings.penetration_tolerance,
            samples: samples.iter().map(ContactSamples::len).collect(),
            feature_samples: samples.iter().map(|s| s.features).collect(),
            derived_surface_triangles: surface_triangles,
            thickness: samples.iter().map(|s| s.thickness).collect(),
            self_contact: self_exclusion.iter().map(Option::is_some).collect(),
            stiffness: stiffness.clone(),
            worst_penetration: 0.0,
            worst_penetration_fraction: 0.0,
            worst_visible_penetration: 0.0,
            worst_visible_penetration_fraction: 0.0,
            worst_visible_at: None,
            surface_points: surface
                .iter()
                .map(|p| p.as_ref().map_or(0, SurfacePoints::len))
                .collect(),
            steps_over_tolerance: 0,
            step_ms_mean: 0.0,
            steps: Vec::new(),
        };
        let sims: Vec<&ReducedSim> = objects.iter().map(SceneObject::sim).collect();
        let contact = WorldContact {
            world: ContactWorld::new(
                &sims,
                samples,
                mu,
                settings.friction_velocity,
                stiffness,
                settings.penetration_tolerance,
                self_exclusion,
                settings.solver,
                settings.hessian_precision,
            ),
            surface,
            tolerance: settings.penetration_tolerance,
            warned: Default::default(),
            last_islands: Vec::new(),
            summary,
        };
        contact.check_start(objects, &shapes)?;
        Ok(contact)
    }

    /// Refuse objects that start interpenetrating: a sample of one inside the other's
    /// placed shape, or two samples overlapping by more than the tolerance.
    fn check_start(&self, objects: &[SceneObject], shapes: &[Option<&Shape>]) -> Result<()> {
        let n = objects.len();
        for a in 0..n {
            for b in 0..n {
                if a == b {
                    continue;
                }
                let (oa, ob) = (&objects[a], &objects[b]);
                let w = &self.world;
                let d = w.samples(a).thickness + w.samples(b).thickness;
                let pair = [w.positions(a), w.positions(b)];
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
                let (ra, rb) = (&w.samples(a).radius, &w.samples(b).radius);
                if let Some(c) = cands.iter().find(|c| {
                    let (p, q) = (pair[0][c.i], pair[1][c.j]);
                    let r = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
                    ra[c.i] + rb[c.j] - r > self.tolerance * diag
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
                let Some(shape) = shapes[b] else { continue };
                let pl = &ob.spec().placement;
                let r = match &pl.rotation {
                    Some(aa) => {
                        let len = aa.axis.iter().map(|v| v * v).sum::<f64>().sqrt();
                        rotation_matrix(&aa.axis.map(|v| v / len), aa.degrees.to_radians())
                    }
                    None => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                };
                let local: Vec<Point3> = w
                    .positions(a)
                    .iter()
                    .map(|x| {
                        let y: [f64; 3] = std::array::from_fn(|k| x[k] - pl.translation[k]);
                        std::array::from_fn(|k| (0..3).map(|m| r[m][k] * y[m]).sum())
                    })
                    .collect();
                if let Some(inside) = shape.contains(&local) {
                    if let Some(i) = inside.iter().position(|&v| v) {
                        let p = w.positions(a)[i];
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

    /// The contact state the steps are solved with.
    pub(super) fn contact_world(&self) -> &ContactWorld {
        &self.world
    }

    /// One world step with contact; every object's report, in object order.
    pub(super) fn step(
        &mut self,
        objects: &mut [SceneObject],
        warnings: &mut Vec<Warning>,
    ) -> Vec<StepReport> {
        let sw = Stopwatch::start();
        let n = objects.len();
        let mut sims: Vec<&mut ReducedSim> = objects.iter_mut().map(|o| o.sim_mut()).collect();
        let out = self.world.step(&mut sims);
        self.last_islands.clone_from(&out.island_solves);
        if out.stiffened > 0 {
            self.summary.stiffness = self.world.stiffness().to_vec();
        }
        let reports: Vec<StepReport> = out
            .reports
            .into_iter()
            .zip(objects.iter_mut())
            .map(|(r, o)| o.record(r, warnings))
            .collect();
        let (visible, visible_fraction, spot) = self.visible_penetration(objects);
        let mut row = ContactStepRow {
            step: reports.first().map_or(0, |r| r.step),
            wall_ms: 0.0,
            object_pairs_tested: n * (n.saturating_sub(1)) / 2,
            object_pairs_near: out.object_pairs_near,
            sample_pairs_active: out.sample_pairs_active,
            penetration: out.penetration,
            penetration_fraction: out.penetration_fraction,
            visible_penetration: visible,
            visible_penetration_fraction: visible_fraction,
            islands: out.islands,
            regrouped: out.regrouped,
            stiffened: out.stiffened,
        };
        if row.penetration_fraction > self.tolerance {
            self.summary.steps_over_tolerance += 1;
            if let Some((a, b)) = out.deepest_pair {
                if self.warned.insert((a, b)) {
                    warnings.push(Warning::Penetration {
                        first: objects[a].name().to_string(),
                        second: objects[b].name().to_string(),
                        step: row.step,
                        depth: row.penetration,
                        fraction: row.penetration_fraction,
                        tolerance: self.tolerance,
                    });
                }
            }
        }
        let s = &mut self.summary;
        s.worst_penetration = s.worst_penetration.max(row.penetration);
        s.worst_penetration_fraction = s.worst_penetration_fraction.max(row.penetration_fraction);
        if row.visible_penetration_fraction > s.worst_visible_penetration_fraction {
            s.worst_visible_at = spot.map(|v| VisibleSpot {
                step: row.step,
                ..v
            });
        }
        s.worst_visible_penetration = s.worst_visible_penetration.max(row.visible_penetration);
        s.worst_visible_penetration_fraction = s
            .worst_visible_penetration_fraction
            .max(row.visible_penetration_fraction);
        row.wall_ms = sw.elapsed() * 1e3;
        let k = s.steps.len() as f64;
        s.step_ms_mean = (s.step_ms_mean * k + row.wall_ms) / (k + 1.0);
        s.steps.push(row);
        reports
    }

    /// The deepest reach of an object's own surface points into another object's sample
    /// envelope now: (metres, fraction of the smaller rest diagonal of the two, where: the
    /// spot with its step left 0 for the caller).
    fn visible_penetration(&self, objects: &[SceneObject]) -> (f64, f64, Option<VisibleSpot>) {
        let n = objects.len();
        let samples: Vec<&[Point3]> = (0..n).map(|i| self.world.positions(i)).collect();
        let thickness: Vec<f64> = (0..n).map(|i| self.world.samples(i).thickness).collect();
        // Surface points lie within t sqrt(3) of their samples (a box corner), so only objects
        // whose sample boxes come within 2 (t_a + t_b) of another's need theirs deformed.
        let boxes: Vec<Option<Aabb>> = samples.iter().map(|x| Aabb::from_points(x)).collect();
        let meets = |a: usize, b: usize| match (boxes[a], boxes[b]) {
            (Some(p), Some(q)) => {
                let r = 2.0 * (thickness[a] + thickness[b]);
                (0..3).all(|d| p.min[d] <= q.max[d] + r && q.min[d] <= p.max[d] + r)
            }
            _ => false,
        };
        let surface: Vec<Vec<Point3>> = (0..n)
            .map(|i| match &self.surface[i] {
                Some(p) if (0..n).any(|j| j != i && meets(i, j)) => p.positions(objects[i].sim()),
                _ => Vec::new(),
            })
            .collect();
        let radii: Vec<&[f64]> = (0..n)
            .map(|i| self.world.samples(i).radius.as_slice())
            .collect();
        match deepest_visible(&surface, &samples, &radii) {
            Some(d) if d.depth > 0.0 => {
                let (a, b) = (d.object, d.other);
                let diag = objects[a].sim().diagonal().min(objects[b].sim().diagonal());
                let at = self.surface[a].as_ref().map(|p| p.rest[d.point]);
                let spot = at.map(|rest_point| VisibleSpot {
                    step: 0,
                    surface_object: objects[a].name().to_string(),
                    surface_index: a,
                    other_object: objects[b].name().to_string(),
                    other_index: b,
                    rest_point,
                });
                (d.depth, d.depth / diag, spot)
            }
            _ => (0.0, 0.0, None),
        }
    }
}

/// The contact sample count of object `o` (shape `shape`): its own `contact_samples`, else
/// `contact.samples`, else the default from its size.
fn sample_count(o: &SceneObject, shape: &Shape, settings: &ContactSettings) -> usize {
    o.spec()
        .contact_samples
        .or(settings.samples)
        .unwrap_or_else(|| default_count(shape, settings.radius))
}

/// Refuse contact samples (`counts`, one per object; None: none) whose memory
/// ([`crate::sim::contact::samples::sample_bytes`], summed over the objects) exceeds what the
/// machine has ([`crate::precompute::memory::available_memory`]).
fn check_sample_memory(objects: &[SceneObject], counts: &[Option<usize>]) -> Result<()> {
    let Some((available, source)) = crate::precompute::memory::available_memory()? else {
        return Ok(());
    };
    let (mut bytes, mut count) = (0u64, 0usize);
    for (o, n) in objects.iter().zip(counts) {
        let Some(n) = *n else { continue };
        count = count.saturating_add(n);
        let handles = o.basis().modes();
        bytes = bytes.saturating_add(crate::sim::contact::samples::sample_bytes(n, handles));
    }
    if bytes > available {
        return Err(Error::param(
            "contact.samples",
            count,
            format!(
                "the scene's {count} contact samples would need about {:.2} GB, more than the \
                 {:.2} GB available ({source}); use fewer contact samples per object",
                bytes as f64 / 1e9,
                available as f64 / 1e9
            ),
        ));
    }
    Ok(())
}
