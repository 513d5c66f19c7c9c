//! One option's value as a door hands it over: the command line gives text (a switch `true`), a manifest's JSON
//! and Python's keywords give booleans, whole numbers, numbers and text. Each option's parser in
//! [`super::table`] reads it through these accessors, so every door accepts the same values and refuses the same
//! ones with the same words.

/// A value given for an option, before the option's parser reads it.
#[derive(Clone, Debug, PartialEq)]
pub enum OptionValue {
    /// `true`/`false` (a switch given on the command line is `true`).
    Bool(bool),
    /// A whole number.
    Int(i64),
    /// A number with a fraction.
    Number(f64),
    /// Text: the command line's value, a JSON or Python string, a path.
    Text(String),
}

impl From<bool> for OptionValue {
    fn from(value: bool) -> Self {
        OptionValue::Bool(value)
    }
}

impl From<i64> for OptionValue {
    fn from(value: i64) -> Self {
        OptionValue::Int(value)
    }
}

impl From<u32> for OptionValue {
    fn from(value: u32) -> Self {
        OptionValue::Int(i64::from(value))
    }
}

impl From<f64> for OptionValue {
    fn from(value: f64) -> Self {
        OptionValue::Number(value)
    }
}

impl From<&str> for OptionValue {
    fn from(value: &str) -> Self {
        OptionValue::Text(value.to_string())
    }
}

impl From<String> for OptionValue {
    fn from(value: String) -> Self {
        OptionValue::Text(value)
    }
}

impl From<&std::path::Path> for OptionValue {
    fn from(value: &std::path::Path) -> Self {
        OptionValue::Text(value.to_string_lossy().into_owned())
    }
}

impl OptionValue {
    /// A JSON value of a manifest's `options` object: a boolean, a number or a string (`null` is no value).
    pub fn from_json(value: &serde_json::Value) -> Result<Option<OptionValue>, String> {
        Ok(Some(match value {
            serde_json::Value::Null => return Ok(None),
            serde_json::Value::Bool(b) => OptionValue::Bool(*b),
            serde_json::Value::Number(n) => match n.as_i64() {
                Some(i) => OptionValue::Int(i),
                None => OptionValue::Number(n.as_f64().ok_or("a number out of range")?),
            },
            serde_json::Value::String(s) => OptionValue::Text(s.clone()),
            other => return Err(format!("{other}: expected a boolean, a number or a string")),
        }))
    }

    /// The value as JSON (how `bvhc options --list` shows examples).
    pub fn to_json(&self) -> serde_json::Value {
        match self {
            OptionValue::Bool(b) => serde_json::json!(b),
            OptionValue::Int(i) => serde_json::json!(i),
            OptionValue::Number(x) => serde_json::json!(x),
            OptionValue::Text(s) => serde_json::json!(s),
        }
    }

    /// The value as the command line would spell it.
    pub fn to_text(&self) -> String {
        match self {
            OptionValue::Bool(b) => b.to_string(),
            OptionValue::Int(i) => i.to_string(),
            OptionValue::Number(x) => x.to_string(),
            OptionValue::Text(s) => s.clone(),
        }
    }

    /// `true` or `false`.
    pub(super) fn boolean(&self) -> Result<bool, String> {
        match self {
            OptionValue::Bool(b) => Ok(*b),
            OptionValue::Text(t) if t == "true" => Ok(true),
            OptionValue::Text(t) if t == "false" => Ok(false),
            _ => Err("expected true or false".to_string()),
        }
    }

    /// A whole number from 0 (text of digits too; never a boolean or a fraction).
    pub(super) fn count(&self) -> Result<u64, String> {
        const EXPECTED: &str = "expected a whole number from 0";
        match self {
            OptionValue::Int(i) => u64::try_from(*i).map_err(|_| EXPECTED.to_string()),
            OptionValue::Text(t) => t.trim().parse().map_err(|_| EXPECTED.to_string()),
            _ => Err(EXPECTED.to_string()),
        }
    }

    /// A finite number (a whole number or text of one too).
    pub(super) fn number(&self) -> Result<f64, String> {
        let number = match self {
            OptionValue::Number(x) => Some(*x),
            OptionValue::Int(i) => Some(*i as f64),
            OptionValue::Text(t) => t.trim().parse::<f64>().ok(),
            OptionValue::Bool(_) => None,
        };
        number.filter(|x| x.is_finite()).ok_or_else(|| "expected a finite number".to_string())
    }

    /// Text.
    pub(super) fn text(&self) -> Result<&str, String> {
        match self {
            OptionValue::Text(t) => Ok(t),
            _ => Err("expected a string".to_string()),
        }
    }

    /// One of `choices` by name (`pre-split`; `pre_split` is accepted too).
    pub(super) fn choice<T: Copy>(&self, choices: &[(&str, T)]) -> Result<T, String> {
        let names: Vec<&str> = choices.iter().map(|(n, _)| *n).collect();
        let expected = || format!("expected one of {}", names.join(", "));
        let text = self.text().map_err(|_| expected())?.replace('_', "-");
        choices.iter().find(|(n, _)| *n == text).map(|(_, v)| *v).ok_or_else(expected)
    }
}
