//! User text in one-line messages: clipped and with control characters
//! escaped, so a value of a megabyte or with line breaks in it (an attribute,
//! a regressor, a JSON string) still gives one short line.

/// `s` with control characters and line separators escaped (`\n`,
/// `\u{2028}`).
pub(crate) fn escaped(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if c.is_control() || matches!(c, '\u{2028}' | '\u{2029}') {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// User text quoted in a message: whole up to 200 characters, else its first
/// 120 characters, an ellipsis and its length; escaped as [`escaped`].
pub(crate) fn shown(src: &str) -> String {
    let n = src.chars().count();
    if n <= 200 {
        escaped(src)
    } else {
        let head: String = src.chars().take(120).collect();
        format!("{}... ({n} characters)", escaped(&head))
    }
}

/// A whole message as one line of at most some 600 characters: escaped as
/// [`escaped`], the middle of a longer one elided (user text inside it is the
/// likely cause).
pub(crate) fn one_line(msg: &str) -> String {
    const HEAD: usize = 420;
    const TAIL: usize = 160;
    let n = msg.chars().count();
    if n <= HEAD + TAIL + 20 {
        return escaped(msg);
    }
    let head: String = msg.chars().take(HEAD).collect();
    let tail: String = msg.chars().skip(n - TAIL).collect();
    format!(
        "{} [... {} characters ...] {}",
        escaped(&head),
        n - HEAD - TAIL,
        escaped(&tail)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_and_multi_line_text_becomes_one_short_line() {
        assert_eq!(shown("beta_deg"), "beta_deg");
        assert_eq!(shown("a\nb\u{2028}c"), "a\\nb\\u{2028}c");
        let long = "x".repeat(5000);
        assert_eq!(
            shown(&long),
            format!("{}... (5000 characters)", "x".repeat(120))
        );
        let msg = format!("file.dml:3: <b name=\"{long}\">: bad\nvalue; fix it");
        let line = one_line(&msg);
        assert!(!line.contains('\n') && line.chars().count() < 650, "{line}");
        assert!(line.starts_with("file.dml:3: <b name=\"xxx"), "{line}");
        assert!(line.ends_with("\\nvalue; fix it"), "{line}");
        assert!(line.contains("[... 4462 characters ...]"), "{line}");
        assert_eq!(one_line("short"), "short");
    }
}
