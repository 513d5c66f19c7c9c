//! A small, strict JSON reader (RFC 8259) for the metadata section's checks (V23, V26-V28, V36-V39), so that
//! verifying a file needs no serialization framework. It builds a tree of [`Value`]s; numbers keep their exact
//! integer value when they are written as one, and their nearest f64 (Rust's correctly rounded parse).
//!
//! Bounded: nesting deeper than [`MAX_DEPTH`] is an error (no recursion limit is left to the stack), and the
//! tree is at most a small multiple of the text's size.

use std::fmt;
use std::ops::Range;

/// Deepest nesting of arrays and objects accepted.
pub(crate) const MAX_DEPTH: usize = 128;

/// A JSON value.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Value {
    Null,
    Bool(bool),
    Number(Number),
    String(String),
    Array(Vec<Value>),
    Object(Map),
}

/// A JSON number: its nearest f64, and its value as an integer when the text is a non-negative integer that
/// fits a `u64` (no fraction, no exponent), as `serde_json` gives it; and where its text stands in the parsed
/// text (so that a writer can replace it and leave every other byte alone).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Number {
    text: String,
    value: f64,
    integer: Option<u64>,
    start: usize,
}

impl Number {
    /// The nearest f64.
    pub(crate) fn value(&self) -> f64 {
        self.value
    }

    /// The byte range of the number's text in the text [`parse_object`] read.
    #[cfg_attr(not(feature = "write"), allow(dead_code))]
    pub(crate) fn span(&self) -> Range<usize> {
        self.start..self.start + self.text.len()
    }
}

/// A JSON object: its members in the order written, each with the byte range of its text (from the name's
/// opening quote to the value's end) in the parsed text; a repeated name's last member counts.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Map(Vec<(String, Value, Range<usize>)>);

impl Map {
    /// The value of the last member named `key`.
    pub(crate) fn get(&self, key: &str) -> Option<&Value> {
        self.0.iter().rev().find(|(name, ..)| name == key).map(|(_, value, _)| value)
    }

    /// The object value of the last member named `key`.
    pub(crate) fn object(&self, key: &str) -> Option<&Map> {
        self.get(key).and_then(Value::as_object)
    }

    /// The number value of the last member named `key`, as its nearest f64.
    pub(crate) fn number(&self, key: &str) -> Option<f64> {
        self.get(key).and_then(Value::as_f64)
    }

    /// The bytes to cut from the parsed text to remove the last member named `key`, with one of the commas
    /// around it, so that what is left is the object without that member: from the previous member's end, or
    /// else up to the next member's start, or else the member alone.
    #[cfg_attr(not(feature = "write"), allow(dead_code))]
    pub(crate) fn removal_span(&self, key: &str) -> Option<Range<usize>> {
        let index = self.0.iter().rposition(|(name, ..)| name == key)?;
        let span = &self.0[index].2;
        Some(match (index.checked_sub(1).map(|i| &self.0[i].2), self.0.get(index + 1)) {
            (Some(previous), _) => previous.end..span.end,
            (None, Some((.., next))) => span.start..next.start,
            (None, None) => span.clone(),
        })
    }

    /// Where a new last member goes in the parsed text, and whether it needs a comma before it: after the last
    /// member, or after the opening brace of an empty object (`None` there: the caller finds the brace).
    #[cfg_attr(not(feature = "write"), allow(dead_code))]
    pub(crate) fn end_of_members(&self) -> Option<usize> {
        self.0.last().map(|(.., span)| span.end)
    }
}

impl Value {
    pub(crate) fn get(&self, key: &str) -> Option<&Value> {
        self.as_object().and_then(|object| object.get(key))
    }
    pub(crate) fn as_object(&self) -> Option<&Map> {
        if let Value::Object(object) = self { Some(object) } else { None }
    }
    pub(crate) fn as_array(&self) -> Option<&Vec<Value>> {
        if let Value::Array(array) = self { Some(array) } else { None }
    }
    pub(crate) fn as_str(&self) -> Option<&str> {
        if let Value::String(string) = self { Some(string) } else { None }
    }
    pub(crate) fn as_bool(&self) -> Option<bool> {
        if let Value::Bool(value) = self { Some(*value) } else { None }
    }
    pub(crate) fn as_f64(&self) -> Option<f64> {
        if let Value::Number(number) = self { Some(number.value) } else { None }
    }
    pub(crate) fn as_u64(&self) -> Option<u64> {
        if let Value::Number(number) = self { number.integer } else { None }
    }
    pub(crate) fn as_number(&self) -> Option<&Number> {
        if let Value::Number(number) = self { Some(number) } else { None }
    }
}

impl fmt::Display for Value {
    /// Compact JSON (numbers as written), for error messages.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Null => write!(f, "null"),
            Value::Bool(value) => write!(f, "{value}"),
            Value::Number(number) => write!(f, "{}", number.text),
            Value::String(string) => write!(f, "{string:?}"),
            Value::Array(array) => {
                write!(f, "[")?;
                for (i, value) in array.iter().enumerate() {
                    write!(f, "{}{value}", if i > 0 { "," } else { "" })?;
                }
                write!(f, "]")
            }
            Value::Object(object) => {
                write!(f, "{{")?;
                for (i, (name, value, _)) in object.0.iter().enumerate() {
                    write!(f, "{}{name:?}:{value}", if i > 0 { "," } else { "" })?;
                }
                write!(f, "}}")
            }
        }
    }
}

/// Parses `text` as exactly one JSON object (whitespace around it allowed); the error names the byte offset.
pub(crate) fn parse_object(text: &str) -> Result<Map, String> {
    let mut parser = Parser { bytes: text.as_bytes(), at: 0 };
    parser.skip_whitespace();
    if parser.peek() != Some(b'{') {
        return Err(parser.error("expected an object"));
    }
    let value = parser.value(0)?;
    parser.skip_whitespace();
    if parser.at != parser.bytes.len() {
        return Err(parser.error("trailing characters after the object"));
    }
    match value {
        Value::Object(object) => Ok(object),
        _ => Err("not an object".to_string()),
    }
}

struct Parser<'t> {
    bytes: &'t [u8],
    at: usize,
}

impl Parser<'_> {
    fn error(&self, what: &str) -> String {
        format!("{what} at byte {}", self.at)
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.at).copied()
    }

    fn skip_whitespace(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.at += 1;
        }
    }

    fn expect(&mut self, literal: &str) -> Result<(), String> {
        if self.bytes[self.at..].starts_with(literal.as_bytes()) {
            self.at += literal.len();
            Ok(())
        } else {
            Err(self.error(&format!("expected {literal}")))
        }
    }

    fn value(&mut self, depth: usize) -> Result<Value, String> {
        self.skip_whitespace();
        match self.peek() {
            Some(b'{') | Some(b'[') if depth >= MAX_DEPTH => Err(self.error("nested too deeply")),
            Some(b'{') => self.object(depth),
            Some(b'[') => self.array(depth),
            Some(b'"') => self.string().map(Value::String),
            Some(b't') => self.expect("true").map(|()| Value::Bool(true)),
            Some(b'f') => self.expect("false").map(|()| Value::Bool(false)),
            Some(b'n') => self.expect("null").map(|()| Value::Null),
            Some(b'-' | b'0'..=b'9') => self.number().map(Value::Number),
            Some(_) => Err(self.error("unexpected character")),
            None => Err(self.error("unexpected end")),
        }
    }

    fn object(&mut self, depth: usize) -> Result<Value, String> {
        self.at += 1;
        let mut members = Vec::new();
        self.skip_whitespace();
        if self.peek() == Some(b'}') {
            self.at += 1;
            return Ok(Value::Object(Map(members)));
        }
        loop {
            self.skip_whitespace();
            if self.peek() != Some(b'"') {
                return Err(self.error("expected a member name"));
            }
            let start = self.at;
            let name = self.string()?;
            self.skip_whitespace();
            self.expect(":")?;
            let value = self.value(depth + 1)?;
            members.push((name, value, start..self.at));
            self.skip_whitespace();
            match self.peek() {
                Some(b',') => self.at += 1,
                Some(b'}') => {
                    self.at += 1;
                    return Ok(Value::Object(Map(members)));
                }
                _ => return Err(self.error("expected , or }")),
            }
        }
    }

    fn array(&mut self, depth: usize) -> Result<Value, String> {
        self.at += 1;
        let mut values = Vec::new();
        self.skip_whitespace();
        if self.peek() == Some(b']') {
            self.at += 1;
            return Ok(Value::Array(values));
        }
        loop {
            values.push(self.value(depth + 1)?);
            self.skip_whitespace();
            match self.peek() {
                Some(b',') => self.at += 1,
                Some(b']') => {
                    self.at += 1;
                    return Ok(Value::Array(values));
                }
                _ => return Err(self.error("expected , or ]")),
            }
        }
    }

    fn string(&mut self) -> Result<String, String> {
        self.at += 1;
        let mut out = String::new();
        loop {
            let start = self.at;
            while let Some(byte) = self.peek() {
                if byte == b'"' || byte == b'\\' || byte < 0x20 {
                    break;
                }
                self.at += 1;
            }
            // The text is UTF-8 (a &str) and the run stops only at ASCII bytes, so it is whole characters.
            out.push_str(std::str::from_utf8(&self.bytes[start..self.at]).map_err(|_| self.error("bad UTF-8"))?);
            match self.peek() {
                Some(b'"') => {
                    self.at += 1;
                    return Ok(out);
                }
                Some(b'\\') => {
                    self.at += 1;
                    let escape = self.peek().ok_or_else(|| self.error("unterminated escape"))?;
                    self.at += 1;
                    match escape {
                        b'"' => out.push('"'),
                        b'\\' => out.push('\\'),
                        b'/' => out.push('/'),
                        b'b' => out.push('\u{8}'),
                        b'f' => out.push('\u{c}'),
                        b'n' => out.push('\n'),
                        b'r' => out.push('\r'),
                        b't' => out.push('\t'),
                        b'u' => out.push(self.unicode_escape()?),
                        _ => return Err(self.error("unknown escape")),
                    }
                }
                Some(_) => return Err(self.error("control character in a string")),
                None => return Err(self.error("unterminated string")),
            }
        }
    }

    /// The character of a `\uXXXX` escape (after the `u`), joining a surrogate pair.
    fn unicode_escape(&mut self) -> Result<char, String> {
        let high = self.hex4()?;
        let code = if (0xD800..0xDC00).contains(&high) {
            self.expect("\\u").map_err(|_| self.error("lone high surrogate"))?;
            let low = self.hex4()?;
            if !(0xDC00..0xE000).contains(&low) {
                return Err(self.error("bad low surrogate"));
            }
            0x10000 + ((high - 0xD800) << 10) + (low - 0xDC00)
        } else {
            high
        };
        char::from_u32(code).ok_or_else(|| self.error("lone surrogate"))
    }

    fn hex4(&mut self) -> Result<u32, String> {
        let digits = self.bytes.get(self.at..self.at + 4).ok_or_else(|| self.error("short \\u escape"))?;
        let text = std::str::from_utf8(digits).map_err(|_| self.error("bad \\u escape"))?;
        let value = u32::from_str_radix(text, 16).map_err(|_| self.error("bad \\u escape"))?;
        if !text.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(self.error("bad \\u escape"));
        }
        self.at += 4;
        Ok(value)
    }

    fn number(&mut self) -> Result<Number, String> {
        let start = self.at;
        let digits = |parser: &mut Self| {
            let from = parser.at;
            while matches!(parser.peek(), Some(b'0'..=b'9')) {
                parser.at += 1;
            }
            parser.at > from
        };
        if self.peek() == Some(b'-') {
            self.at += 1;
        }
        if self.peek() == Some(b'0') {
            self.at += 1;
        } else if !digits(self) {
            return Err(self.error("expected a digit"));
        }
        let mut integer = true;
        if self.peek() == Some(b'.') {
            self.at += 1;
            integer = false;
            if !digits(self) {
                return Err(self.error("expected a digit after ."));
            }
        }
        if matches!(self.peek(), Some(b'e' | b'E')) {
            self.at += 1;
            integer = false;
            if matches!(self.peek(), Some(b'+' | b'-')) {
                self.at += 1;
            }
            if !digits(self) {
                return Err(self.error("expected a digit in the exponent"));
            }
        }
        let text = std::str::from_utf8(&self.bytes[start..self.at]).map_err(|_| self.error("bad number"))?;
        let value: f64 = text.parse().map_err(|_| self.error("bad number"))?;
        if !value.is_finite() {
            return Err(self.error("number out of range"));
        }
        let integer = if integer { text.parse::<u64>().ok() } else { None };
        Ok(Number { text: text.to_string(), value, integer, start })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_what_the_metadata_holds_and_refuses_what_json_forbids() {
        let text = r#" {"a": 1, "b": [true, false, null], "c": {"d": -2.5e-3, "e": "x\"\u00e9\ud83d\ude00"}, "a": 18446744073709551615} "#;
        let object = parse_object(text).unwrap();
        assert_eq!(object.get("a").and_then(Value::as_u64), Some(u64::MAX), "the last repeated member counts");
        assert_eq!(object.get("c").and_then(|c| c.get("d")).and_then(Value::as_f64), Some(-2.5e-3));
        assert_eq!(object.get("c").and_then(|c| c.get("e")).and_then(Value::as_str), Some("x\"é😀"));
        assert_eq!(object.get("b").and_then(Value::as_array).map(Vec::len), Some(3));
        assert_eq!(
            object.get("c").and_then(|c| c.get("d")).and_then(Value::as_number).map(|n| &text[n.span()]),
            Some("-2.5e-3")
        );
        assert_eq!(parse_object(r#"{"n": 1.0}"#).unwrap().get("n").and_then(Value::as_u64), None);
        assert_eq!(
            parse_object(r#"{"n": 7.7771232602156735}"#).unwrap().get("n").and_then(Value::as_f64),
            Some(7.7771232602156735)
        );
        for bad in [
            "",
            "[]",
            "{",
            "{}x",
            r#"{"a"}"#,
            r#"{"a":01}"#,
            r#"{"a":1.}"#,
            r#"{"a":-}"#,
            r#"{"a":1e999}"#,
            r#"{"a":"\x"}"#,
            "{\"a\":\"\u{1}\"}",
            r#"{"a":"\ud800"}"#,
            r#"{"a":[1,]}"#,
            r#"{"a":tru}"#,
            r#"{,}"#,
        ] {
            assert!(parse_object(bad).is_err(), "{bad:?}");
        }
        let deep = format!("{{\"a\":{}{}}}", "[".repeat(MAX_DEPTH + 1), "]".repeat(MAX_DEPTH + 1));
        assert!(parse_object(&deep).unwrap_err().contains("nested too deeply"));
        let fine = format!("{{\"a\":{}{}}}", "[".repeat(MAX_DEPTH - 2), "]".repeat(MAX_DEPTH - 2));
        assert!(parse_object(&fine).is_ok());
    }

    #[test]
    fn a_member_removed_by_its_span_leaves_the_object_without_it() {
        let cut = |text: &str, key: &str| {
            let span = parse_object(text).unwrap().removal_span(key)?;
            let mut left = text.to_string();
            left.replace_range(span, "");
            Some(left)
        };
        assert_eq!(cut(r#"{"a": 1, "b": {"c": 2}, "d": 3}"#, "b").as_deref(), Some(r#"{"a": 1, "d": 3}"#));
        assert_eq!(cut(r#"{ "b": [1, 2] ,"d": 3}"#, "b").as_deref(), Some(r#"{ "d": 3}"#));
        assert_eq!(cut(r#"{"a": 1, "b": 2 }"#, "b").as_deref(), Some(r#"{"a": 1 }"#));
        assert_eq!(cut(r#"{ "b": 2 }"#, "b").as_deref(), Some(r#"{  }"#));
        assert_eq!(cut(r#"{"b": 1, "a": 0, "b": 2}"#, "b").as_deref(), Some(r#"{"b": 1, "a": 0}"#), "the last counts");
        assert_eq!(cut(r#"{"a": {"b": 1}}"#, "b"), None, "members of nested objects are not the object's");
        for text in [r#"{"a": 1, "b": {"c": 2}, "d": 3}"#, r#"{ "b": [1, 2] ,"d": 3}"#, r#"{ "b": 2 }"#] {
            assert!(parse_object(&cut(text, "b").unwrap()).is_ok());
        }
    }
}
