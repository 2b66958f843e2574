//! The shape and discretization options shared by `modes`, `export` and `compare`: one flag
//! per row of the library's option table (`freeform::precompute::table`), with its help line
//! and its default from there.

use clap::builder::PossibleValuesParser;
use clap::parser::ValueSource;
use clap::{value_parser, Arg, ArgAction, ArgMatches, Args, Command, FromArgMatches};
use freeform::geometry::{Shape, ShapeOptions};
use freeform::io::read_shape;
use freeform::precompute::{
    BasisChoices, BasisOption, BasisOptions, OptionTable, Value, ValueKind,
};

/// The discretization, material and eigensolver-tolerance flags of every command that builds
/// H_w and M (`modes`, `export`, `compare`): the rows of [`OptionTable::basis`] that every
/// command takes, with the library's defaults.
#[derive(Debug, Clone, Default)]
pub struct BasisArgs {
    /// The options the flags ask for (not yet validated; the solver is the default LOBPCG).
    pub choices: BasisChoices,
}

impl BasisArgs {
    /// The pipeline options these flags ask for (not yet validated).
    pub fn options(&self) -> BasisOptions {
        self.choices.options.clone()
    }

    /// How to read the shape.
    pub fn shape_options(&self) -> ShapeOptions {
        self.choices.shape.clone()
    }
}

/// The rows of `table` that are flags of every basis-building command.
fn flag_rows(table: &OptionTable) -> impl Iterator<Item = &'static BasisOption> + '_ {
    table
        .rows()
        .filter(|r| r.every_command && r.name.flag.is_some())
}

/// The argument id of a row: its flag without dashes, in snake case (`support_neighbor`).
fn id(row: &BasisOption) -> String {
    row.name
        .flag
        .unwrap_or(row.name.library)
        .trim_start_matches('-')
        .replace('-', "_")
}

/// The flag of `row`, as the derive macro would write it for a field of its kind.
fn arg(row: &'static BasisOption) -> Arg {
    let id = id(row);
    let long = row.name.flag.unwrap_or_default().trim_start_matches('-');
    let arg = Arg::new(id.clone()).long(long).help(row.name.help);
    let arg = match row.kind {
        ValueKind::Switch => return arg.action(ArgAction::SetTrue),
        ValueKind::Count => arg.value_parser(value_parser!(usize)),
        ValueKind::Number => arg.value_parser(value_parser!(f64)),
        ValueKind::Choice(names) => arg.value_parser(PossibleValuesParser::new(names())),
        // Texts are checked as they are parsed: the row applies them to the defaults.
        ValueKind::Text | ValueKind::Texts => {
            arg.value_parser(move |s: &str| -> Result<String, String> {
                (row.set)(
                    row,
                    &mut BasisChoices::default(),
                    Value::Text(s.to_string()),
                )
                .map(|()| s.to_string())
                .map_err(|e| e.to_string())
            })
        }
    };
    let arg = arg.value_name(id.to_uppercase()).action(match row.kind {
        ValueKind::Texts => ArgAction::Append,
        _ => ArgAction::Set,
    });
    let arg = match (row.default)(&BasisChoices::default()) {
        Some(d) => arg.default_value(d.to_string()),
        None => arg,
    };
    row.conflicts_with.iter().fold(arg, |arg, other| {
        let other = other.flag.unwrap_or_default().trim_start_matches('-');
        arg.conflicts_with(other.replace('-', "_"))
    })
}

/// The flags of `table`'s rows, added to `cmd` in the table's order.
pub fn add_flags(cmd: Command, table: &OptionTable) -> Command {
    flag_rows(table).fold(cmd, |cmd, row| cmd.arg(arg(row)))
}

/// The options the command line gave (the library's defaults for the others), applied in
/// the table's order.
pub fn read_flags(m: &ArgMatches, table: &OptionTable) -> Result<BasisChoices, clap::Error> {
    let mut given = Vec::new();
    for row in flag_rows(table) {
        let id = id(row);
        if m.value_source(&id) != Some(ValueSource::CommandLine) {
            continue;
        }
        let value = match row.kind {
            ValueKind::Count => m.get_one::<usize>(&id).copied().map(Value::Count),
            ValueKind::Number => m.get_one::<f64>(&id).copied().map(Value::Number),
            ValueKind::Switch => Some(Value::Switch(m.get_flag(&id))),
            ValueKind::Choice(_) | ValueKind::Text => {
                m.get_one::<String>(&id).cloned().map(Value::Text)
            }
            ValueKind::Texts => m
                .get_many::<String>(&id)
                .map(|v| Value::Texts(v.cloned().collect())),
        };
        given.extend(value.map(|v| (row, v)));
    }
    table
        .apply(given)
        .map_err(|e| clap::Error::raw(clap::error::ErrorKind::InvalidValue, e))
}

impl Args for BasisArgs {
    fn augment_args(cmd: Command) -> Command {
        add_flags(cmd, &OptionTable::basis())
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

impl FromArgMatches for BasisArgs {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        Ok(BasisArgs {
            choices: read_flags(m, &OptionTable::basis())?,
        })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

/// A shape and its [`BasisArgs`] (`export`, `compare`).
#[derive(Args)]
pub struct ShapeArgs {
    /// The shape: box:LX,LY,LZ, sphere:R, or a .obj / .stl / .off / .ply file (see `modes --help`).
    pub shape: String,
    /// Discretization, material and tolerance.
    #[command(flatten)]
    pub basis: BasisArgs,
}

impl ShapeArgs {
    /// The pipeline options (validated) and the parsed shape.
    pub fn build(&self) -> Result<(Shape, BasisOptions), Box<dyn std::error::Error>> {
        let opts = self.basis.options();
        opts.validate()?;
        let shape = read_shape(&self.shape, &self.basis.shape_options())?;
        Ok((shape, opts))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;
    use freeform::options::{self, Front, OptionName};
    use freeform::precompute::table::BASIS_OPTIONS;

    /// A toy option, the rounds of coverage repair (a library field no front end sets): its
    /// whole definition is its names and its row.
    static TOY_NAME: OptionName = OptionName {
        library: "BasisOptions::coverage_repair_rounds",
        flag: Some("--coverage-rounds"),
        scene: None,
        python: Some("coverage_rounds"),
        c: None,
        value_prefix: "",
        help: "Rounds of local support enlargement before a coverage error",
    };

    static TOY: BasisOption = BasisOption {
        name: &TOY_NAME,
        kind: ValueKind::Count,
        default: |d| Some(Value::Count(d.options.coverage_repair_rounds)),
        set: |row, c, v| {
            c.options.coverage_repair_rounds = row.count(v)?;
            Ok(())
        },
        every_command: true,
        conflicts_with: &[],
    };

    #[test]
    fn a_toy_option_joins_every_front_end_with_one_registration_line() {
        let table = OptionTable::basis().with(&TOY);
        let cmd = add_flags(Command::new("toy"), &table);
        // The command line: a flag with its help line and the library's default.
        let help = cmd.clone().render_long_help().to_string();
        assert!(
            help.contains("--coverage-rounds <COVERAGE_ROUNDS>")
                && help.contains("Rounds of local support enlargement before a coverage error")
                && help.contains("[default: 3]"),
            "{help}"
        );
        let parse = |args: &[&str]| {
            let m = cmd.clone().try_get_matches_from(args).unwrap();
            read_flags(&m, &table).unwrap()
        };
        let given = parse(&["toy", "--coverage-rounds", "5", "--kernels", "200"]);
        assert_eq!(given.options.coverage_repair_rounds, 5);
        assert_eq!(given.options.kernels, 200);
        assert_eq!(parse(&["toy"]), BasisChoices::default());
        // Python's keywords (what `python/src/basis.rs` looks a keyword up with).
        assert!(table.names(Front::Python).contains(&"coverage_rounds"));
        let row = table.find(Front::Python, "coverage_rounds").unwrap();
        let applied = table.apply(vec![(row, Value::Count(7))]).unwrap();
        assert_eq!(applied.options.coverage_repair_rounds, 7);
        // Messages name it as each front end sets it (no scene key: the library's name).
        let advice = || format!("raise {TOY_NAME}");
        assert_eq!(Front::Flags.scope(advice), "raise --coverage-rounds");
        assert_eq!(Front::Python.scope(advice), "raise coverage_rounds");
        assert_eq!(
            Front::Scene.scope(advice),
            "raise BasisOptions::coverage_repair_rounds"
        );
        // Not in the built-in table.
        assert!(OptionTable::basis()
            .find(Front::Flags, "--coverage-rounds")
            .is_none());
    }

    /// The subcommand `name` of the real command line.
    fn subcommand(name: &str) -> Command {
        crate::Cli::command()
            .find_subcommand(name)
            .unwrap_or_else(|| panic!("no subcommand {name}"))
            .clone()
    }

    fn long(cmd: &Command, flag: &str) -> Option<Arg> {
        let flag = flag.trim_start_matches('-');
        cmd.get_arguments()
            .find(|a| a.get_long() == Some(flag))
            .cloned()
    }

    #[test]
    fn every_basis_command_takes_the_tables_flags_with_its_defaults() {
        let defaults = BasisChoices::default();
        for name in ["modes", "export", "compare"] {
            let cmd = subcommand(name);
            for row in BASIS_OPTIONS.iter().filter(|r| r.every_command) {
                let flag = row.name.flag.unwrap();
                let arg = long(&cmd, flag).unwrap_or_else(|| panic!("{name}: no {flag}"));
                let shown: Vec<String> = arg
                    .get_default_values()
                    .iter()
                    .map(|v| v.to_string_lossy().into_owned())
                    .collect();
                let want: Vec<String> = match (row.kind, (row.default)(&defaults)) {
                    (ValueKind::Switch, _) | (_, None) => vec![],
                    (_, Some(d)) => vec![d.to_string()],
                };
                if !matches!(row.kind, ValueKind::Switch) {
                    assert_eq!(shown, want, "{name} {flag}");
                }
            }
        }
        // The eigensolver flags `modes` writes out itself carry the table's names.
        let modes = subcommand("modes");
        for name in [
            &options::SOLVER,
            &options::SLEPC,
            &options::PETSC_OPTIONS,
            &options::LOBPCG,
        ] {
            let flag = name.flag.unwrap();
            let arg = long(&modes, flag).unwrap_or_else(|| panic!("modes: no {flag}"));
            assert_eq!(
                arg.get_help().map(ToString::to_string).as_deref(),
                Some(name.help),
                "{flag}"
            );
        }
    }
}
