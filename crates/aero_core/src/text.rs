//! User text in one-line messages: clipped and with control characters
//! escaped, so a value of a megabyte or with line breaks in it (an attribute,
//! a regressor, a JSON string) still gives one short line.

fn needs_escape(c: char) -> bool {
    c.is_control() || matches!(c, '\u{2028}' | '\u{2029}')
}

/// Characters `c` takes once escaped.
fn width(c: char) -> usize {
    if needs_escape(c) {
        c.escape_default().count()
    } else {
        1
    }
}

fn push(out: &mut String, c: char) {
    if needs_escape(c) {
        out.extend(c.escape_default());
    } else {
        out.push(c);
    }
}

/// `s` with control characters and line separators escaped (`\n`,
/// `\u{2028}`).
pub(crate) fn escaped(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    s.chars().for_each(|c| push(&mut out, c));
    out
}

/// The escaped form of the first characters of `s` filling at most `room`
/// characters, and how many characters of `s` it holds.
fn head(s: &str, room: usize) -> (String, usize) {
    let (mut out, mut used, mut n) = (String::new(), 0, 0);
    for c in s.chars() {
        if used + width(c) > room {
            break;
        }
        used += width(c);
        n += 1;
        push(&mut out, c);
    }
    (out, n)
}

/// Whether `s` escaped fits in `room` characters (without building it).
fn fits(s: &str, room: usize) -> bool {
    let mut used = 0;
    s.chars().all(|c| {
        used += width(c);
        used <= room
    })
}

/// User text quoted in a message: whole when it takes at most 200 characters
/// escaped (see [`escaped`]), else its first 120 (escaped), an ellipsis and
/// its length in characters.
pub(crate) fn shown(src: &str) -> String {
    if fits(src, 200) {
        return escaped(src);
    }
    let (h, _) = head(src, 120);
    format!("{h}... ({} characters)", src.chars().count())
}

/// A whole message as one line of at most some 600 characters: escaped as
/// [`escaped`], the middle of a longer one elided (user text inside it is the
/// likely cause).
pub(crate) fn one_line(msg: &str) -> String {
    const HEAD: usize = 420;
    const TAIL: usize = 160;
    if fits(msg, HEAD + TAIL + 20) {
        return escaped(msg);
    }
    let (h, nh) = head(msg, HEAD);
    let (mut used, mut nt) = (0, 0);
    for c in msg.chars().rev() {
        if used + width(c) > TAIL {
            break;
        }
        used += width(c);
        nt += 1;
    }
    let n = msg.chars().count();
    let mut tail = String::new();
    msg.chars().skip(n - nt).for_each(|c| push(&mut tail, c));
    format!("{h} [... {} characters ...] {tail}", n - nh - nt)
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
        assert!(line.contains("[... 4463 characters ...]"), "{line}");
        assert_eq!(one_line("short"), "short");
        // Escapes count towards the length: 300 control characters are clipped.
        let ctl = "\u{11}".repeat(300);
        let s = shown(&ctl);
        assert!(
            s.chars().count() < 200 && s.ends_with("... (300 characters)"),
            "{s}"
        );
        let line = one_line(&format!("m.dml:1: {ctl}"));
        assert!(
            line.chars().count() < 650 && !line.contains('\u{11}'),
            "{line}"
        );
    }
}
