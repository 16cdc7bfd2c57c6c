//! NumPy `.npy` arrays (`numpy.lib.format`, versions 1.0 to 3.0): the reader of the float32
//! tensors NBRDF networks are stored in.
//!
//! The format is read here rather than with `npyz`: its header parser takes exponential time
//! on nested brackets and allocates the header length a file claims (up to 4 GiB) before
//! reading it. This one checks every length against the input first and parses the header
//! dictionary in one pass.

use crate::{Error, Result};
use std::path::Path;

/// Parses one float32 little-endian C-order array and checks its shape; returns the values
/// in row-major order.
///
/// Errors name `path`.
pub fn read_f32(bytes: &[u8], shape: &[u64], path: &Path) -> Result<Vec<f32>> {
    let header = NpyHeader::parse(bytes)
        .map_err(|e| Error::invalid_file(path, format!("not a valid .npy file: {e}")))?;
    match header.descr {
        NpyDescr::Plain(ref d) if d == "<f4" => {}
        NpyDescr::Plain(ref d) => {
            return Err(Error::invalid_file(
                path,
                format!("dtype {d}, expected little-endian float32 (<f4)"),
            ))
        }
        NpyDescr::Structured => {
            return Err(Error::invalid_file(
                path,
                "structured dtype, expected little-endian float32 (<f4)",
            ))
        }
    }
    if header.shape != shape {
        return Err(Error::invalid_file(
            path,
            format!("shape {:?}, expected {:?}", header.shape, shape),
        ));
    }
    if header.fortran_order && shape.len() > 1 {
        return Err(Error::invalid_file(
            path,
            "Fortran-ordered array, expected C order",
        ));
    }
    let count: u64 = shape.iter().product();
    let data = &bytes[header.data_offset..];
    if data.len() as u64 != 4 * count {
        return Err(Error::invalid_file(
            path,
            format!(
                "cannot read the data: {} bytes after the header, expected {} ({count} float32)",
                data.len(),
                4 * count
            ),
        ));
    }
    let values: Vec<f32> = data
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid_file(
            path,
            format!("non-finite weight {} at element {i}", values[i]),
        ));
    }
    Ok(values)
}

/// The `descr` of a `.npy` header.
#[derive(Debug, PartialEq)]
enum NpyDescr {
    /// A type string such as `<f4`.
    Plain(String),
    /// A list of fields (a record dtype).
    Structured,
}

/// What a `.npy` header says.
#[derive(Debug)]
struct NpyHeader {
    descr: NpyDescr,
    fortran_order: bool,
    shape: Vec<u64>,
    /// Offset of the array data in the file.
    data_offset: usize,
}

impl NpyHeader {
    /// Reads the magic string, version, header length and header dictionary
    /// (`{'descr': ..., 'fortran_order': ..., 'shape': (...)}`, in any order, each key once,
    /// no other keys); the reason of a failure is returned for the caller's message.
    fn parse(bytes: &[u8]) -> std::result::Result<NpyHeader, String> {
        let magic = b"\x93NUMPY";
        if bytes.len() < 10 || !bytes.starts_with(magic) {
            return Err("no .npy magic string".to_string());
        }
        let (length, text_offset) = match (bytes[6], bytes[7]) {
            (1, 0) => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10usize),
            (2, 0) | (3, 0) => {
                let b = bytes
                    .get(8..12)
                    .ok_or_else(|| "truncated header".to_string())?;
                (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize, 12)
            }
            (major, minor) => return Err(format!("unsupported version {major}.{minor}")),
        };
        let text = text_offset
            .checked_add(length)
            .and_then(|end| bytes.get(text_offset..end))
            .ok_or_else(|| {
                format!(
                    "the header claims {length} bytes, the file has {} after the preamble",
                    bytes.len() - text_offset.min(bytes.len())
                )
            })?;
        let text = std::str::from_utf8(text).map_err(|_| "header is not UTF-8".to_string())?;
        let mut p = PyLiteral {
            s: text.as_bytes(),
            at: 0,
        };
        let (mut descr, mut fortran_order, mut shape) = (None, None, None);
        p.expect(b'{')?;
        loop {
            if p.eat(b'}') {
                break;
            }
            let key = p.string()?;
            p.expect(b':')?;
            let duplicate = match key.as_str() {
                "descr" => descr.replace(p.descr()?).is_some(),
                "fortran_order" => fortran_order.replace(p.boolean()?).is_some(),
                "shape" => shape.replace(p.int_tuple()?).is_some(),
                other => return Err(format!("unexpected header key '{other}'")),
            };
            if duplicate {
                return Err(format!("header key '{key}' appears twice"));
            }
            if !p.eat(b',') {
                p.expect(b'}')?;
                break;
            }
        }
        p.skip_space();
        if p.at != p.s.len() {
            return Err("text after the header dictionary".to_string());
        }
        let missing = |key: &str| format!("header has no '{key}'");
        Ok(NpyHeader {
            descr: descr.ok_or_else(|| missing("descr"))?,
            fortran_order: fortran_order.ok_or_else(|| missing("fortran_order"))?,
            shape: shape.ok_or_else(|| missing("shape"))?,
            data_offset: text_offset + length,
        })
    }
}

/// A one-pass reader of the Python literals a `.npy` header holds.
struct PyLiteral<'a> {
    s: &'a [u8],
    at: usize,
}

impl PyLiteral<'_> {
    fn skip_space(&mut self) {
        while self.s.get(self.at).is_some_and(u8::is_ascii_whitespace) {
            self.at += 1;
        }
    }

    /// Skips white space, then consumes `c` if it is next.
    fn eat(&mut self, c: u8) -> bool {
        self.skip_space();
        let found = self.s.get(self.at) == Some(&c);
        if found {
            self.at += 1;
        }
        found
    }

    fn expect(&mut self, c: u8) -> std::result::Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!(
                "malformed header: expected '{}' at byte {}",
                c as char, self.at
            ))
        }
    }

    /// A quoted string without escapes (NumPy writes keys and type strings so).
    fn string(&mut self) -> std::result::Result<String, String> {
        self.skip_space();
        let quote = match self.s.get(self.at) {
            Some(&q @ (b'\'' | b'"')) => q,
            _ => {
                return Err(format!(
                    "malformed header: expected a string at byte {}",
                    self.at
                ))
            }
        };
        let start = self.at + 1;
        let len = self.s[start..]
            .iter()
            .position(|&c| c == quote || c == b'\\')
            .filter(|&n| self.s[start + n] == quote)
            .ok_or_else(|| "malformed header: unterminated or escaped string".to_string())?;
        self.at = start + len + 1;
        Ok(String::from_utf8_lossy(&self.s[start..start + len]).into_owned())
    }

    /// A type string, or a list (a record dtype, not read further).
    fn descr(&mut self) -> std::result::Result<NpyDescr, String> {
        self.skip_space();
        if self.s.get(self.at) == Some(&b'[') {
            return Ok(NpyDescr::Structured);
        }
        self.string().map(NpyDescr::Plain)
    }

    fn boolean(&mut self) -> std::result::Result<bool, String> {
        self.skip_space();
        for (word, value) in [(&b"True"[..], true), (&b"False"[..], false)] {
            if self.s[self.at..].starts_with(word) {
                self.at += word.len();
                return Ok(value);
            }
        }
        Err(format!(
            "malformed header: expected True or False at byte {}",
            self.at
        ))
    }

    /// `()`, `(n,)` or `(n, m, ...)` of non-negative integers (a Python 2 `L` suffix
    /// allowed).
    fn int_tuple(&mut self) -> std::result::Result<Vec<u64>, String> {
        self.expect(b'(')?;
        let mut dims = Vec::new();
        loop {
            if self.eat(b')') {
                return Ok(dims);
            }
            let start = self.at;
            while self.s.get(self.at).is_some_and(u8::is_ascii_digit) {
                self.at += 1;
            }
            let digits = std::str::from_utf8(&self.s[start..self.at]).unwrap_or("");
            let dim = digits
                .parse::<u64>()
                .map_err(|_| format!("malformed header: bad shape dimension at byte {start}"))?;
            dims.push(dim);
            self.eat(b'L');
            if !self.eat(b',') {
                self.expect(b')')?;
                return Ok(dims);
            }
        }
    }
}

