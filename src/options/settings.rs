//! A preset and overrides set option by option by name: how every door (the command line, `Conversion::set`,
//! Python's keywords, a `bvhc batch` manifest) hands its options over, through the parsers of [`super::table`].

use super::resolve::{OptionsError, Overrides, resolve};
use super::spec::Kind;
use super::table;
use super::value::OptionValue;
use super::{ConvertOptions, Preset};

/// A preset and the options set over it; [`Settings::resolve`] checks them together.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Settings {
    /// The preset the overrides apply to.
    pub preset: Preset,
    /// What was set.
    pub overrides: Overrides,
}

impl Settings {
    /// `preset` with nothing overridden.
    pub fn new(preset: Preset) -> Settings {
        Settings { preset, overrides: Overrides::default() }
    }

    /// Sets the option `name` (a name of [`table::OPTIONS`], or the positive name of a `no_*` switch with a
    /// boolean: `splits: false` is `no_splits: true`). An unknown name or a value the option does not take is an
    /// error naming the option; a setting another makes inert is refused later, by [`Settings::resolve`].
    pub fn set(&mut self, name: &str, value: impl Into<OptionValue>) -> Result<(), OptionsError> {
        let value = value.into();
        let spec = table::find(name).ok_or_else(|| OptionsError::Unknown { name: name.to_string() })?;
        let value = match (spec.inverse == Some(name), &value) {
            (true, OptionValue::Bool(b)) => OptionValue::Bool(!b),
            (true, _) => return Err(OptionsError::invalid(name, "expected true or false")),
            (false, _) => value,
        };
        if spec.kind == Kind::Switch && value.boolean().is_err() {
            return Err(OptionsError::invalid(name, "expected true or false"));
        }
        (spec.set)(self, &value).map_err(|why| OptionsError::invalid(name, why))
    }

    /// The options these settings make, checked ([`resolve`]).
    pub fn resolve(&self) -> Result<ConvertOptions, OptionsError> {
        resolve(self.preset, &self.overrides)
    }
}
