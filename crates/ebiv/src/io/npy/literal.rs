//! A parser for the small subset of Python literals a `.npy` header uses (formats.md §12):
//! dicts, lists, tuples, strings, integers (with Python 2's `L` suffix), floats, `True`,
//! `False` and `None`. Nesting depth is bounded so no input can exhaust the stack.

/// A Python literal value.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Py {
    Str(String),
    Int(i128),
    Float(f64),
    Bool(bool),
    None,
    List(Vec<Py>),
    Tuple(Vec<Py>),
    Dict(Vec<(Py, Py)>),
}

const MAX_DEPTH: usize = 32;

/// Parse `text` as one literal followed only by whitespace.
pub(crate) fn parse_literal(text: &str) -> Result<Py, String> {
    let mut p = Parser {
        s: text.as_bytes(),
        pos: 0,
    };
    let value = p.value(0)?;
    p.skip_ws();
    if p.pos < p.s.len() {
        return Err(format!("unexpected text at character {}", p.pos));
    }
    Ok(value)
}

struct Parser<'a> {
    s: &'a [u8],
    pos: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Option<u8> {
        self.s.get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r' | 0)) {
            self.pos += 1;
        }
    }

    fn value(&mut self, depth: usize) -> Result<Py, String> {
        if depth > MAX_DEPTH {
            return Err("nested too deeply".into());
        }
        self.skip_ws();
        match self.peek() {
            None => Err("unexpected end".into()),
            Some(b'{') => {
                self.pos += 1;
                let mut entries = Vec::new();
                loop {
                    self.skip_ws();
                    if self.peek() == Some(b'}') {
                        self.pos += 1;
                        return Ok(Py::Dict(entries));
                    }
                    let key = self.value(depth + 1)?;
                    self.skip_ws();
                    if self.peek() != Some(b':') {
                        return Err(format!("expected `:` at character {}", self.pos));
                    }
                    self.pos += 1;
                    let value = self.value(depth + 1)?;
                    entries.push((key, value));
                    if !self.separator(b'}')? {
                        self.pos += 1;
                        return Ok(Py::Dict(entries));
                    }
                }
            }
            Some(open @ (b'[' | b'(')) => {
                self.pos += 1;
                let close = if open == b'[' { b']' } else { b')' };
                let mut items = Vec::new();
                let mut trailing_comma = false;
                loop {
                    self.skip_ws();
                    if self.peek() == Some(close) {
                        self.pos += 1;
                        break;
                    }
                    items.push(self.value(depth + 1)?);
                    trailing_comma = self.separator(close)?;
                    if !trailing_comma {
                        self.pos += 1;
                        break;
                    }
                }
                // `(5)` is the number 5 in Python; `(5,)` a tuple.
                if open == b'(' && items.len() == 1 && !trailing_comma {
                    return items.pop().ok_or_else(|| "empty".into());
                }
                Ok(if open == b'[' {
                    Py::List(items)
                } else {
                    Py::Tuple(items)
                })
            }
            Some(q @ (b'\'' | b'"')) => self.string(q),
            Some(b'T' | b'F' | b'N') => {
                let rest = &self.s[self.pos..];
                for (word, value) in [
                    (&b"True"[..], Py::Bool(true)),
                    (b"False", Py::Bool(false)),
                    (b"None", Py::None),
                ] {
                    if rest.starts_with(word) {
                        self.pos += word.len();
                        return Ok(value);
                    }
                }
                Err(format!("unknown word at character {}", self.pos))
            }
            Some(b'-' | b'+' | b'0'..=b'9' | b'.') => self.number(),
            Some(c) => Err(format!(
                "unexpected character `{}` at {}",
                c.escape_ascii(),
                self.pos
            )),
        }
    }

    /// After an item: consume a `,` and return true, or see `close` (not consumed) and
    /// return false.
    fn separator(&mut self, close: u8) -> Result<bool, String> {
        self.skip_ws();
        match self.peek() {
            Some(b',') => {
                self.pos += 1;
                Ok(true)
            }
            Some(c) if c == close => Ok(false),
            _ => Err(format!(
                "expected `,` or `{}` at character {}",
                close as char, self.pos
            )),
        }
    }

    fn string(&mut self, quote: u8) -> Result<Py, String> {
        self.pos += 1;
        let mut bytes = Vec::new();
        loop {
            let Some(c) = self.peek() else {
                return Err("unterminated string".into());
            };
            self.pos += 1;
            match c {
                b'\\' => {
                    let Some(e) = self.peek() else {
                        return Err("unterminated string".into());
                    };
                    self.pos += 1;
                    bytes.push(match e {
                        b'n' => b'\n',
                        b't' => b'\t',
                        b'r' => b'\r',
                        b'0' => 0,
                        other => other,
                    });
                }
                c if c == quote => break,
                c => bytes.push(c),
            }
        }
        Ok(Py::Str(String::from_utf8_lossy(&bytes).into_owned()))
    }

    fn number(&mut self) -> Result<Py, String> {
        let start = self.pos;
        while matches!(
            self.peek(),
            Some(b'-' | b'+' | b'0'..=b'9' | b'.' | b'e' | b'E')
        ) {
            self.pos += 1;
        }
        let text = std::str::from_utf8(&self.s[start..self.pos]).map_err(|e| e.to_string())?;
        // Python 2 long integers: `10L`.
        if matches!(self.peek(), Some(b'L' | b'l')) {
            self.pos += 1;
        }
        if let Ok(i) = text.parse::<i128>() {
            return Ok(Py::Int(i));
        }
        text.parse::<f64>()
            .map(Py::Float)
            .map_err(|_| format!("bad number `{text}`"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_numpy_header_dicts() {
        let v = parse_literal(
            "{'descr': [('t', '<i8'), ('', '|V3')], 'fortran_order': False, 'shape': (10L,), }  \n",
        )
        .unwrap();
        let Py::Dict(entries) = v else { panic!() };
        assert_eq!(entries.len(), 3);
        assert_eq!(entries[2].1, Py::Tuple(vec![Py::Int(10)]));
        assert_eq!(parse_literal("(5)").unwrap(), Py::Int(5));
        assert_eq!(parse_literal("()").unwrap(), Py::Tuple(vec![]));
        assert_eq!(parse_literal("\"a\\'b\"").unwrap(), Py::Str("a'b".into()));
    }

    #[test]
    fn rejects_garbage_without_panicking() {
        for text in [
            "", "{", "{'a'", "{'a':", "[1,", "((((", "'abc", "{1:2,,}", "Tru", "-", "1e",
        ] {
            assert!(parse_literal(text).is_err(), "{text:?}");
        }
        let deep = "[".repeat(10_000);
        assert!(parse_literal(&deep).is_err());
    }
}
