//! The fast path of reading a numeric measurement log (CSV): a header line, then rows of
//! comma-separated decimal numbers.
//!
//! [`parse_numeric_csv`] takes the file's bytes and either returns every row, parsed, or
//! declines (`None`) whenever the text holds anything beyond the plain case (quoted cells,
//! a cell that is not a finite number, a row of another width, a lone carriage return,
//! text that is not UTF-8, ...). The caller then reads the file with its general reader,
//! which says what is wrong and where: the messages of bad files stay in one place (the
//! Python reader, `prrrp.csvio`), and this parser only ever accepts what that reader
//! accepts, with the same values (both round correctly to the nearest `f64`).

/// The rows of a numeric CSV text, as [`parse_numeric_csv`] read them.
#[derive(Debug, Clone, PartialEq)]
pub struct NumericCsv {
    /// The header line as written (without its line end, byte-order mark removed).
    pub header: String,
    /// 1-based line number of the header (after blank and comment lines).
    pub header_line: usize,
    /// Cells per row: the header's comma-separated fields.
    pub width: usize,
    /// Data rows read (blank and comment lines skipped).
    pub rows: usize,
    /// The numbers, row after row (`rows · width` values).
    pub values: Vec<f64>,
}

/// Reads a CSV text whose first line that is neither blank nor a comment (`#` after
/// spaces/tabs) is a header, followed by rows of `width` finite decimal numbers (spaces
/// and tabs around a cell allowed; blank and comment lines skipped; `\n` or `\r\n` line
/// ends; an optional UTF-8 byte-order mark). Returns `None` for anything else, including
/// a text without a header line, so that a more general reader can report it.
pub fn parse_numeric_csv(bytes: &[u8]) -> Option<NumericCsv> {
    let text = std::str::from_utf8(bytes).ok()?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // A lone carriage return also ends a line for the general reader (universal newlines),
    // also inside what would be a comment here: declined.
    let mut lone_cr = false;
    let mut lines = text.split('\n').enumerate().filter_map(|(k, line)| {
        let line = line.strip_suffix('\r').unwrap_or(line);
        lone_cr |= line.contains('\r');
        let content = line.trim_start_matches(is_pad);
        (!content.is_empty() && !content.starts_with('#')).then_some((k + 1, line))
    });
    let (header_line, header) = lines.next()?;
    if header.contains('"') {
        return None;
    }
    let width = header.split(',').count();
    // A first guess of the rows from the header's length keeps the vector's regrowth
    // (a copy of everything read) to a few times.
    let mut values = Vec::with_capacity(text.len() / (header.len().max(8) * 2) * width);
    let mut rows = 0usize;
    for (_, line) in lines {
        let mut cells = 0usize;
        for cell in line.split(',') {
            let cell = cell.trim_matches(is_pad);
            let x: f64 = cell.parse().ok()?;
            if !x.is_finite() {
                return None;
            }
            values.push(x);
            cells += 1;
        }
        if cells != width {
            return None;
        }
        rows += 1;
    }
    if lone_cr {
        return None;
    }
    Some(NumericCsv {
        header: header.to_owned(),
        header_line,
        width,
        rows,
        values,
    })
}

/// What may precede `#` on a comment line, and pad a cell.
fn is_pad(c: char) -> bool {
    c == ' ' || c == '\t'
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Option<NumericCsv> {
        parse_numeric_csv(text.as_bytes())
    }

    #[test]
    fn reads_rows_after_comments_and_blank_lines() {
        let t = parse("\u{feff}# a log\n\n t , q1\r\n0,1.5\n  # note\n\n0.5e-1, -2E3 \n1.,.25")
            .unwrap();
        assert_eq!(t.header, " t , q1");
        assert_eq!((t.header_line, t.width, t.rows), (3, 2, 3));
        assert_eq!(t.values, vec![0.0, 1.5, 0.05, -2000.0, 1.0, 0.25]);
    }

    #[test]
    fn values_round_like_a_decimal_to_binary_conversion() {
        // The shortest representations of awkward doubles read back to the same bits.
        let xs = [
            0.1,
            1.0 / 3.0,
            f64::MIN_POSITIVE,
            5e-324,
            1.7976931348623157e308,
            -0.0,
        ];
        let text = format!("x\n{}", xs.map(|x| format!("{x:?}")).join("\n"));
        let t = parse(&text).unwrap();
        for (a, b) in t.values.iter().zip(xs) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
    }

    #[test]
    fn declines_what_it_does_not_read_plainly() {
        for text in [
            "",
            "# only a comment\n\n",
            "t,q1\n0,nan\n",
            "t,q1\n0,inf\n",
            "t,q1\n0,1e999\n",
            "t,q1\n0,abc\n",
            "t,q1\n0,\n",
            "t,q1\n0,1,2\n",
            "t,q1\n0\n",
            "t,q1\n0,1_000\n",
            "\"t\",q1\n0,1\n",
            "t,q1\n\"0\",1\n",
            "t,q1\r0,1\r",
            "t,q1\n0,1\n# a comment\r2,3\n",
            "t,q1\n0,\u{a0}1\n",
        ] {
            assert_eq!(parse(text), None, "{text:?}");
        }
        assert_eq!(parse_numeric_csv(b"t,q1\n0,1\n# \xff\n"), None);
    }

    #[test]
    fn a_header_without_rows_is_read() {
        let t = parse("t,q1,tau1\n").unwrap();
        assert_eq!((t.width, t.rows, t.values.len()), (3, 0, 0));
    }
}
