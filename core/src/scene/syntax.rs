//! Messages for RON syntax errors that name the real fault. The parser reports where it stopped
//! and what token it wanted there, which often is not the mistake: `width: 64.5` stops at `.5`
//! wanting a comma, a string missing its closing quote stops lines later, and a value nested too
//! deeply suggests changing a parser option. These are recognised from the text and explained.

use ron::error::{Error, SpannedError};

/// Nesting depth the RON parser accepts (its default recursion limit).
pub const MAX_NESTING: usize = 128;

/// The position (1-based line and column) and message of a syntax error in `text`.
pub fn explain(text: &str, e: &SpannedError) -> (usize, usize, String) {
    let (line, col) = (e.span.start.line, e.span.start.col);
    if let Some((l, c)) = unterminated_string(text, line, col) {
        return (
            l,
            c,
            "this string has no closing `\"` on its line (strings in a scene never span lines)"
                .into(),
        );
    }
    if matches!(e.code, Error::ExceededRecursionLimit) {
        return (
            line,
            col,
            format!(
                "brackets are nested more than {MAX_NESTING} deep here; a scene never needs that many"
            ),
        );
    }
    let Some(offset) = byte_offset(text, line, col) else {
        return (line, col, e.code.to_string());
    };
    let Some((start, literal)) = number_around(text, offset) else {
        if matches!(e.code, Error::ExpectedInteger)
            && let Some(field) = field_before(text, offset)
        {
            return (
                line,
                col,
                format!("`{field}` must be a whole number ({})", e.code),
            );
        }
        return (line, col, e.code.to_string());
    };
    let (line, col) = line_col(text, start);
    let field = field_before(text, start);
    let named = field.map_or("this value".to_string(), |f| format!("`{f}`"));
    let fractional = literal.contains(['.', 'e', 'E']) && !literal.starts_with("0x");
    if fractional
        && matches!(
            e.code,
            Error::ExpectedComma
                | Error::InvalidIntegerDigit { .. }
                | Error::ExpectedInteger
                | Error::ExpectedStructLikeEnd
                | Error::ExpectedArrayEnd
                | Error::ExpectedMapEnd
        )
    {
        return (
            line,
            col,
            format!("{named} must be a whole number, found `{literal}`"),
        );
    }
    if matches!(e.code, Error::IntegerOutOfBounds) {
        let range = match field {
            Some("seed") => "0..=18446744073709551615",
            _ => "0..=4294967295",
        };
        return (
            line,
            col,
            format!("{named} must be a whole number in {range}, found `{literal}`"),
        );
    }
    (line, col, e.code.to_string())
}

/// The byte offset of a 1-based line and column (in characters), if inside the text.
fn byte_offset(text: &str, line: usize, col: usize) -> Option<usize> {
    let line_start = if line <= 1 {
        0
    } else {
        text.match_indices('\n').nth(line - 2)?.0 + 1
    };
    let rest = &text[line_start..];
    let within = rest
        .char_indices()
        .nth(col.saturating_sub(1))
        .map_or(rest.len(), |(i, _)| i);
    Some(line_start + within)
}

/// The 1-based line and column (in characters) of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset];
    let line = 1 + before.matches('\n').count();
    let col = 1 + before.chars().rev().take_while(|&c| c != '\n').count();
    (line, col)
}

/// The numeric literal that contains or ends at `offset`: its start and text.
fn number_around(text: &str, offset: usize) -> Option<(usize, &str)> {
    let is_part = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '+' | '-');
    let bytes = text.as_bytes();
    let mut start = offset.min(text.len());
    while start > 0 && is_part(bytes[start - 1] as char) {
        start -= 1;
    }
    let mut end = offset.min(text.len());
    while end < text.len() && is_part(bytes[end] as char) {
        end += 1;
    }
    let literal = &text[start..end];
    // A number starts with a digit, or a sign or a dot followed by one.
    let digits = literal.trim_start_matches(['+', '-', '.']);
    digits
        .starts_with(|c: char| c.is_ascii_digit())
        .then_some((start, literal))
}

/// The field name in `name: value` when `offset` is where the value starts.
fn field_before(text: &str, offset: usize) -> Option<&str> {
    let before = text[..offset].trim_end();
    let before = before.strip_suffix(':')?.trim_end();
    let start = before
        .char_indices()
        .rev()
        .find(|(_, c)| !(c.is_ascii_alphanumeric() || *c == '_'))
        .map_or(0, |(i, c)| i + c.len_utf8());
    let name = &before[start..];
    (!name.is_empty() && !name.starts_with(|c: char| c.is_ascii_digit())).then_some(name)
}

/// The start (line, column) of a string literal before the error position that runs past the
/// end of its line or of the file: the likely missing quote.
fn unterminated_string(text: &str, err_line: usize, err_col: usize) -> Option<(usize, usize)> {
    let mut chars = text.char_indices().peekable();
    let mut line = 1;
    let mut col = 1;
    // Advances one character, tracking the position.
    macro_rules! next {
        () => {{
            let item = chars.next();
            if let Some((_, c)) = item {
                if c == '\n' {
                    line += 1;
                    col = 1;
                } else {
                    col += 1;
                }
            }
            item
        }};
    }
    while let Some(&(_, c)) = chars.peek() {
        if (line, col) > (err_line, err_col) {
            return None;
        }
        let (start_line, start_col) = (line, col);
        next!();
        match c {
            '/' if chars.peek().map(|p| p.1) == Some('/') => {
                while let Some(&(_, c)) = chars.peek() {
                    if c == '\n' {
                        break;
                    }
                    next!();
                }
            }
            '/' if chars.peek().map(|p| p.1) == Some('*') => {
                next!();
                let mut prev = ' ';
                while let Some((_, c)) = next!() {
                    if prev == '*' && c == '/' {
                        break;
                    }
                    prev = c;
                }
            }
            '"' => {
                let mut closed = false;
                let mut escaped = false;
                while let Some((_, c)) = next!() {
                    match c {
                        '\n' => break,
                        '\\' if !escaped => {
                            escaped = true;
                            continue;
                        }
                        '"' if !escaped => {
                            closed = true;
                            break;
                        }
                        _ => {}
                    }
                    escaped = false;
                }
                if !closed {
                    return Some((start_line, start_col));
                }
            }
            _ => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(text: &str) -> (usize, usize, String) {
        #[derive(serde::Deserialize, Debug)]
        #[allow(dead_code)]
        struct Film {
            width: u32,
            #[serde(default)]
            name: String,
            #[serde(default)]
            seed: u64,
        }
        let e = ron::from_str::<Film>(text).expect_err("a syntax error");
        explain(text, &e)
    }

    #[test]
    fn fractional_and_out_of_range_integers_are_named() {
        let (l, c, m) = message("(\n  width: 64.5)");
        assert_eq!((l, c), (2, 10));
        assert_eq!(m, "`width` must be a whole number, found `64.5`");
        let (_, _, m) = message("(width: 64e3)");
        assert_eq!(m, "`width` must be a whole number, found `64e3`");
        let (_, _, m) = message("(width: -5)");
        assert_eq!(
            m,
            "`width` must be a whole number in 0..=4294967295, found `-5`"
        );
        let (_, _, m) = message("(width: 1, seed: 99999999999999999999999)");
        assert!(m.contains("`seed` must be a whole number in 0..=18446744073709551615"));
        let (_, _, m) = message("(width: \"big\")");
        assert_eq!(m, "`width` must be a whole number (Expected integer)");
    }

    #[test]
    fn text_that_is_not_ascii_is_sliced_at_character_boundaries() {
        assert_eq!(field_before("(wïdth: 64", 9), Some("dth"));
        assert_eq!(number_around("é64.5é", 3), Some((2, "64.5")));
        // A field name ending in a two-byte character, numbers next to multi-byte text.
        for text in [
            "(wïdth: 64.5)",
            "(width: 64.5é)",
            "(é64.5)",
            "(width: \"ü, seed: 3)",
        ] {
            if let Err(e) = ron::from_str::<ron::Value>(text) {
                let _ = explain(text, &e);
            }
            #[derive(serde::Deserialize, Debug)]
            #[allow(dead_code)]
            struct Film {
                width: u32,
            }
            if let Err(e) = ron::from_str::<Film>(text) {
                let (line, col, message) = explain(text, &e);
                assert!(line >= 1 && col >= 1 && !message.is_empty());
            }
        }
    }

    #[test]
    fn a_missing_closing_quote_is_found_where_the_string_starts() {
        let (l, c, m) = message("(width: 1,\n name: \"abc,\n seed: 3)");
        assert_eq!((l, c), (2, 8));
        assert!(m.contains("no closing `\"`"), "{m}");
        // Quotes in comments and escaped quotes do not count.
        let (_, _, m) = message("// a \"quote\n(width: 1, name: \"a\\\"b\", seed: x)");
        assert!(!m.contains("closing"), "{m}");
    }

    #[test]
    fn deep_nesting_is_explained() {
        #[derive(serde::Deserialize, Debug)]
        #[allow(dead_code)]
        struct Plugin {
            value: ron::Value,
        }
        let text = format!("(value: {}{})", "[".repeat(300), "]".repeat(300));
        let e = ron::from_str::<Plugin>(&text).expect_err("too deep");
        let (_, _, m) = explain(&text, &e);
        assert!(m.contains("nested more than 128 deep"), "{m}");
        assert!(!m.contains("recursion_limit"), "{m}");
    }
}
