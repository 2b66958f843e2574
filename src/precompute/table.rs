//! The option table: every basis option once ([`BasisOption`]), with its names in every front
//! end (a row of [`crate::options`]), its kind of value, its default and how a value is
//! applied. The command line's basis flags and Python's keyword arguments are made from
//! [`OptionTable::basis`]; scene keys and the C API's fields are held to it by tests
//! (`tests/integration/options.rs`, `capi`), since serde and a C struct need their fields
//! written out.
//!
//! Every default is `BasisOptions::default()`'s (and `ShapeOptions::default()`'s): a row reads
//! it, it does not restate it. A new option is a [`BasisOption`] (usually a `static` here)
//! plus one registration line: an entry of [`BASIS_OPTIONS`], or `.with(&ROW)` on a table
//! (docs/architecture.md, "An option").

use super::density::DensityRegion;
use super::options::{BasisOptions, MatrixStorage};
use super::resolution::Resolution;
use super::rkpm::KernelType;
use super::solver::SolverConfig;
use crate::error::Error;
use crate::geometry::ShapeOptions;
use crate::material::Region;
use crate::options::{self, Front, OptionName};
use crate::Result;

/// Everything the basis options set: the pipeline's options and how the shape is read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BasisChoices {
    /// The precomputation's options.
    pub options: BasisOptions,
    /// How a shape file is read (`allow_open_mesh`).
    pub shape: ShapeOptions,
}

/// The kind of value an option takes: how the command line parses it and which Python type
/// it accepts.
#[derive(Debug, Clone, Copy)]
pub enum ValueKind {
    /// A non-negative whole number.
    Count,
    /// A number (f64).
    Number,
    /// On when given (a command-line switch; `True`/`False` in Python).
    Switch,
    /// One of the names `choices()` returns (their serde spellings).
    Choice(fn() -> Vec<&'static str>),
    /// Any text (parsed by the option itself).
    Text,
    /// A list of texts (a repeated flag; a list of str in Python).
    Texts,
}

/// A value given for an option, of its [`ValueKind`].
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// [`ValueKind::Count`].
    Count(usize),
    /// [`ValueKind::Number`].
    Number(f64),
    /// [`ValueKind::Switch`].
    Switch(bool),
    /// [`ValueKind::Choice`] and [`ValueKind::Text`].
    Text(String),
    /// [`ValueKind::Texts`].
    Texts(Vec<String>),
}

impl std::fmt::Display for Value {
    /// As the command line writes it (and shows a default).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Count(n) => write!(f, "{n}"),
            Value::Number(x) => write!(f, "{x}"),
            Value::Switch(b) => write!(f, "{b}"),
            Value::Text(s) => f.write_str(s),
            Value::Texts(v) => f.write_str(&v.join(",")),
        }
    }
}

/// One basis option: a row of the option table.
#[derive(Debug)]
pub struct BasisOption {
    /// Its names in every front end, and its help line.
    pub name: &'static OptionName,
    /// What it takes.
    pub kind: ValueKind,
    /// Its default as [`BasisChoices::default`] holds it; None where there is no fixed default
    /// (an optional value, or a rule the help line states).
    pub default: fn(&BasisChoices) -> Option<Value>,
    /// Apply a value of [`BasisOption::kind`].
    pub set: fn(&BasisOption, &mut BasisChoices, Value) -> Result<()>,
    /// Whether every command that builds a basis takes it as a flag (`modes`, `export`,
    /// `compare`); false for an option only some commands take, each in its own way (the
    /// eigensolver: `modes --solver/--slepc/--petsc-options`, `compare --slepc/--dense`).
    pub every_command: bool,
    /// Options that cannot be given together with this one.
    pub conflicts_with: &'static [&'static OptionName],
}

impl BasisOption {
    /// The value as a count, or an error naming the option (a front end passed another kind).
    pub fn count(&self, v: Value) -> Result<usize> {
        match v {
            Value::Count(n) => Ok(n),
            other => Err(self.wrong_kind(&other)),
        }
    }

    /// The value as a number (a count is one too).
    pub fn number(&self, v: Value) -> Result<f64> {
        match v {
            Value::Number(x) => Ok(x),
            Value::Count(n) => Ok(n as f64),
            other => Err(self.wrong_kind(&other)),
        }
    }

    /// The value as a switch.
    pub fn switch(&self, v: Value) -> Result<bool> {
        match v {
            Value::Switch(b) => Ok(b),
            other => Err(self.wrong_kind(&other)),
        }
    }

    /// The value as text.
    pub fn text(&self, v: Value) -> Result<String> {
        match v {
            Value::Text(s) => Ok(s),
            other => Err(self.wrong_kind(&other)),
        }
    }

    /// The value as a list of texts (one text is a list of one).
    pub fn texts(&self, v: Value) -> Result<Vec<String>> {
        match v {
            Value::Texts(v) => Ok(v),
            Value::Text(s) => Ok(vec![s]),
            other => Err(self.wrong_kind(&other)),
        }
    }

    /// The value as one of [`ValueKind::Choice`]'s names, parsed by `parse`.
    pub fn choice<T>(&self, v: Value, parse: impl Fn(&str) -> Option<T>) -> Result<T> {
        let name = self.text(v)?;
        parse(&name).ok_or_else(|| {
            let ValueKind::Choice(choices) = self.kind else {
                return self.wrong_kind(&Value::Text(name.clone()));
            };
            let mut names: Vec<String> = choices().iter().map(|c| format!("'{c}'")).collect();
            if let Some(Value::Text(d)) = (self.default)(&BasisChoices::default()) {
                for n in names.iter_mut().filter(|n| **n == format!("'{d}'")) {
                    n.push_str(" (default)");
                }
            }
            let last = names.pop().unwrap_or_default();
            Error::InvalidOption {
                option: self.name,
                value: format!("'{name}'"),
                reason: format!("use {} or {last}", names.join(", ")),
            }
        })
    }

    fn wrong_kind(&self, v: &Value) -> Error {
        Error::InvalidOption {
            option: self.name,
            value: format!("{v:?}"),
            reason: format!("expected a value of kind {:?}", self.kind),
        }
    }
}

/// The option table a front end reads: the built-in rows ([`OptionTable::basis`]) and any
/// registered with [`OptionTable::with`], in order (the order of the command line's help).
#[derive(Debug, Clone)]
#[must_use]
pub struct OptionTable {
    rows: Vec<&'static BasisOption>,
}

impl OptionTable {
    /// The built-in basis options ([`BASIS_OPTIONS`]).
    pub fn basis() -> OptionTable {
        OptionTable {
            rows: BASIS_OPTIONS.to_vec(),
        }
    }

    /// The table with `row` registered after the others.
    pub fn with(mut self, row: &'static BasisOption) -> OptionTable {
        self.rows.push(row);
        self
    }

    /// The rows, in order.
    pub fn rows(&self) -> impl Iterator<Item = &'static BasisOption> + '_ {
        self.rows.iter().copied()
    }

    /// The row `front` calls `name` (`"tol"` in [`Front::Python`]), if any.
    pub fn find(&self, front: Front, name: &str) -> Option<&'static BasisOption> {
        self.rows().find(|r| r.name.own_name(front) == Some(name))
    }

    /// The names `front` has for the rows, in order.
    pub fn names(&self, front: Front) -> Vec<&'static str> {
        self.rows().filter_map(|r| r.name.own_name(front)).collect()
    }

    /// The defaults with `given` applied in order (each row at most once; not validated:
    /// [`BasisOptions::validate`] checks the ranges).
    ///
    /// # Errors
    /// [`Error::ConflictingOptions`] for two options that exclude each other; what a row's
    /// `set` refuses (an unknown kernel name, a malformed region or eigensolver).
    pub fn apply(&self, given: Vec<(&'static BasisOption, Value)>) -> Result<BasisChoices> {
        for (row, _) in &given {
            for other in row.conflicts_with {
                if given.iter().any(|(r, _)| std::ptr::eq(r.name, *other)) {
                    return Err(Error::ConflictingOptions {
                        first: row.name,
                        second: other,
                    });
                }
            }
        }
        let mut choices = BasisChoices::default();
        for (row, value) in given {
            (row.set)(row, &mut choices, value)?;
        }
        Ok(choices)
    }
}

/// The built-in basis options, in the command line's order: registering an option is one
/// entry here.
pub static BASIS_OPTIONS: [&BasisOption; 23] = [
    &KERNELS,
    &MODES,
    &POINTS,
    &SPACING,
    &KERNEL,
    &SUPPORT_FACTOR,
    &SUPPORT_NEIGHBOR,
    &TOL,
    &MAX_ITER,
    &MATRIX_STORAGE,
    &YOUNGS,
    &POISSON,
    &DENSITY,
    &VOLUME,
    &VOXEL,
    &ALLOW_OPEN_MESH,
    &REGIONS,
    &DENSITY_BOUNDARIES,
    &DENSITY_INTERFACES,
    &DENSITY_BAND,
    &DENSITY_THIN,
    &DENSITY_REGIONS,
    &EIGENSOLVER,
];

/// A row that every command takes, with no conflicts.
const fn row(
    name: &'static OptionName,
    kind: ValueKind,
    default: fn(&BasisChoices) -> Option<Value>,
    set: fn(&BasisOption, &mut BasisChoices, Value) -> Result<()>,
) -> BasisOption {
    BasisOption {
        name,
        kind,
        default,
        set,
        every_command: true,
        conflicts_with: &[],
    }
}

/// Number of kernels K.
pub static KERNELS: BasisOption = row(
    &options::KERNELS,
    ValueKind::Count,
    |d| Some(Value::Count(d.options.kernels)),
    |row, c, v| {
        c.options.kernels = row.count(v)?;
        Ok(())
    },
);

/// Number of non-constant modes m.
pub static MODES: BasisOption = row(
    &options::MODES,
    ValueKind::Count,
    |d| Some(Value::Count(d.options.modes)),
    |row, c, v| {
        c.options.modes = row.count(v)?;
        Ok(())
    },
);

/// Integration points, a count (default: [`super::default_points`] of K).
pub static POINTS: BasisOption = BasisOption {
    conflicts_with: &[&options::SPACING],
    ..row(
        &options::POINTS,
        ValueKind::Count,
        |_| None,
        |row, c, v| {
            c.options.resolution = Some(Resolution::Count(row.count(v)?));
            Ok(())
        },
    )
};

/// Integration grid spacing, metres.
pub static SPACING: BasisOption = BasisOption {
    conflicts_with: &[&options::POINTS],
    ..row(
        &options::SPACING,
        ValueKind::Number,
        |_| None,
        |row, c, v| {
            c.options.resolution = Some(Resolution::Spacing(row.number(v)?));
            Ok(())
        },
    )
};

/// The kernel window.
pub static KERNEL: BasisOption = row(
    &options::KERNEL,
    ValueKind::Choice(|| KernelType::ALL.iter().map(|k| k.name()).collect()),
    |d| Some(Value::Text(d.options.kernel.name().to_string())),
    |row, c, v| {
        c.options.kernel = row.choice(v, KernelType::from_name)?;
        Ok(())
    },
);

/// The support radius factor.
pub static SUPPORT_FACTOR: BasisOption = row(
    &options::SUPPORT_FACTOR,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.support.factor)),
    |row, c, v| {
        c.options.support.factor = row.number(v)?;
        Ok(())
    },
);

/// The n of the support rule.
pub static SUPPORT_NEIGHBOR: BasisOption = row(
    &options::SUPPORT_NEIGHBOR,
    ValueKind::Count,
    |d| Some(Value::Count(d.options.support.neighbor)),
    |row, c, v| {
        c.options.support.neighbor = row.count(v)?;
        Ok(())
    },
);

/// The eigensolver's relative residual tolerance.
pub static TOL: BasisOption = row(
    &options::TOL,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.tol)),
    |row, c, v| {
        c.options.tol = row.number(v)?;
        Ok(())
    },
);

/// The eigensolver's iteration cap.
pub static MAX_ITER: BasisOption = row(
    &options::MAX_ITER,
    ValueKind::Count,
    |d| Some(Value::Count(d.options.max_iter)),
    |row, c, v| {
        c.options.max_iter = row.count(v)?;
        Ok(())
    },
);

/// How H_w and M are stored.
pub static MATRIX_STORAGE: BasisOption = row(
    &options::MATRIX_STORAGE,
    ValueKind::Choice(|| MatrixStorage::ALL.iter().map(|s| s.name()).collect()),
    |d| Some(Value::Text(d.options.matrix_storage.name().to_string())),
    |row, c, v| {
        c.options.matrix_storage = row.choice(v, MatrixStorage::from_name)?;
        Ok(())
    },
);

/// Young's modulus, Pa.
pub static YOUNGS: BasisOption = row(
    &options::YOUNGS,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.material.youngs)),
    |row, c, v| {
        c.options.material.youngs = row.number(v)?;
        Ok(())
    },
);

/// Poisson ratio.
pub static POISSON: BasisOption = row(
    &options::POISSON,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.material.poisson)),
    |row, c, v| {
        c.options.material.poisson = row.number(v)?;
        Ok(())
    },
);

/// Density, kg/m^3.
pub static DENSITY: BasisOption = row(
    &options::DENSITY,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.material.density)),
    |row, c, v| {
        c.options.material.density = row.number(v)?;
        Ok(())
    },
);

/// A point cloud's total volume, m^3 (default: estimated).
pub static VOLUME: BasisOption = row(
    &options::VOLUME,
    ValueKind::Number,
    |_d| None,
    |row, c, v| {
        c.options.cloud.total_volume = Some(row.number(v)?);
        Ok(())
    },
);

/// A point cloud's voxel edge for the volume estimate, metres (default: from the spacing).
pub static VOXEL: BasisOption = row(
    &options::VOXEL,
    ValueKind::Number,
    |_d| None,
    |row, c, v| {
        c.options.cloud.voxel = Some(row.number(v)?);
        Ok(())
    },
);

/// Accept a mesh with holes.
pub static ALLOW_OPEN_MESH: BasisOption = row(
    &options::ALLOW_OPEN_MESH,
    ValueKind::Switch,
    |d| Some(Value::Switch(d.shape.allow_open_mesh)),
    |row, c, v| {
        c.shape.allow_open_mesh = row.switch(v)?;
        Ok(())
    },
);

/// The boundary regions of a boundary-aware basis.
pub static REGIONS: BasisOption = row(
    &options::REGIONS,
    ValueKind::Texts,
    |_d| None,
    |row, c, v| {
        c.options.boundary_regions = row
            .texts(v)?
            .iter()
            .map(|r| r.parse::<Region>())
            .collect::<Result<_>>()?;
        Ok(())
    },
);

/// The kernel spacing factor near boundary regions.
pub static DENSITY_BOUNDARIES: BasisOption = row(
    &options::DENSITY_BOUNDARIES,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.density.bands.boundaries)),
    |row, c, v| {
        c.options.density.bands.boundaries = row.number(v)?;
        Ok(())
    },
);

/// The kernel spacing factor at material interfaces.
pub static DENSITY_INTERFACES: BasisOption = row(
    &options::DENSITY_INTERFACES,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.density.bands.interfaces)),
    |row, c, v| {
        c.options.density.bands.interfaces = row.number(v)?;
        Ok(())
    },
);

/// The refined bands' half-width, in kernel spacings.
pub static DENSITY_BAND: BasisOption = row(
    &options::DENSITY_BAND,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.density.bands.band)),
    |row, c, v| {
        c.options.density.bands.band = row.number(v)?;
        Ok(())
    },
);

/// The largest kernel spacing factor on thin parts.
pub static DENSITY_THIN: BasisOption = row(
    &options::DENSITY_THIN,
    ValueKind::Number,
    |d| Some(Value::Number(d.options.density.bands.thin)),
    |row, c, v| {
        c.options.density.bands.thin = row.number(v)?;
        Ok(())
    },
);

/// User regions with their own kernel spacing factor, `REGION@FACTOR`.
pub static DENSITY_REGIONS: BasisOption = row(
    &options::DENSITY_REGIONS,
    ValueKind::Texts,
    |_d| None,
    |row, c, v| {
        c.options.density.regions = row
            .texts(v)?
            .iter()
            .map(|r| r.parse::<DensityRegion>())
            .collect::<Result<_>>()?;
        Ok(())
    },
);

/// The eigensolver, by [`SolverConfig`]'s text (`lobpcg`, `dense`, `slepc:CONFIG:OPTIONS`).
pub static EIGENSOLVER: BasisOption = BasisOption {
    every_command: false,
    ..row(
        &options::SOLVER,
        ValueKind::Text,
        |d| Some(Value::Text(d.options.solver.to_string())),
        |row, c, v| {
            c.options.solver = row.text(v)?.parse::<SolverConfig>()?;
            Ok(())
        },
    )
};
