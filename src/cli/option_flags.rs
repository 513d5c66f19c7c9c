//! The conversion options' flags, made from the options table (`bvhc::options::OPTIONS`): one flag an option,
//! `--` and its name with `-` for `_`, under its stage's help heading, its help ending in what each preset sets.
//! A value is read by the option's own parser when the command line is read (a bad one is a usage error, exit
//! 2); a ray file (`--train-rays`) is read when the options are applied.

use bvhc::options::{Kind, OPTIONS, OptionSpec, OptionValue, OptionsError, Settings};
use clap::builder::PossibleValuesParser;
use clap::{Arg, ArgAction, ArgMatches, Args, Command, FromArgMatches};

/// The options given on the command line, in the table's order.
#[derive(Clone, Debug, Default)]
pub struct OptionArgs {
    given: Vec<(&'static str, OptionValue)>,
}

impl OptionArgs {
    /// The preset and overrides the flags set; an error names the flag (`--train-rays` whose file cannot be
    /// read or holds a bad ray).
    pub fn settings(&self) -> Result<Settings, OptionsError> {
        let mut settings = Settings::default();
        for (name, value) in &self.given {
            settings.set(name, value.clone())?;
        }
        Ok(settings)
    }
}

impl FromArgMatches for OptionArgs {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let mut given = Vec::new();
        let mut check = Settings::default();
        for spec in OPTIONS {
            let value = match spec.kind {
                Kind::Switch => matches.get_flag(spec.name).then_some(OptionValue::Bool(true)),
                _ => matches.get_one::<String>(spec.name).map(|text| OptionValue::Text(text.clone())),
            };
            let Some(value) = value else { continue };
            if spec.kind != Kind::Path {
                check.set(spec.name, value.clone()).map_err(|error| {
                    let why = match &error {
                        OptionsError::Invalid { why, .. } => why.clone(),
                        other => other.to_string(),
                    };
                    let message = format!("invalid value '{}' for '{}': {why}\n", value.to_text(), spec.flag());
                    clap::Error::raw(clap::error::ErrorKind::ValueValidation, message)
                })?;
            }
            given.push((spec.name, value));
        }
        Ok(OptionArgs { given })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = OptionArgs::from_arg_matches(matches)?;
        Ok(())
    }
}

impl Args for OptionArgs {
    fn augment_args(command: Command) -> Command {
        command.args(OPTIONS.iter().map(flag))
    }

    fn augment_args_for_update(command: Command) -> Command {
        OptionArgs::augment_args(command)
    }
}

/// The flag of one option.
fn flag(spec: &'static OptionSpec) -> Arg {
    let arg = Arg::new(spec.name).long(spec.name.replace('_', "-")).help_heading(spec.stage.heading()).help(format!(
        "{}{}",
        spec.help,
        defaults(spec)
    ));
    match spec.kind {
        Kind::Switch => arg.action(ArgAction::SetTrue),
        Kind::Choice(names) => arg.value_name(spec.value_name).value_parser(PossibleValuesParser::new(names)),
        // `--animation` alone samples every clip.
        Kind::Text if spec.name == "animation" => {
            arg.value_name(spec.value_name).num_args(0..=1).default_missing_value("")
        }
        _ => arg.value_name(spec.value_name),
    }
}

/// ` [default: ...]`: what the presets set, once where they agree; nothing for a switch off under every preset.
pub fn defaults(spec: &OptionSpec) -> String {
    let [fast, balanced, max_quality] = spec.defaults();
    if spec.kind == Kind::Switch && [&fast, &balanced, &max_quality].iter().all(|d| *d == "false") {
        return String::new();
    }
    if spec.name == "preset" {
        return " [default: balanced]".to_string();
    }
    if fast == balanced && balanced == max_quality {
        format!(" [default: {balanced}]")
    } else {
        format!(" [default: fast {fast}, balanced {balanced}, max-quality {max_quality}]")
    }
}
