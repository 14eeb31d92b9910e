//! A compact, non-recursive XML reader for DAVE-ML: one pass over the text
//! builds an arena of nodes (elements and text) in document order, each 24
//! bytes, attributes 20 bytes each, names and text left in the input as byte
//! ranges. Only text or attribute values that unescaping changes (entity and
//! character references, CDATA sections, line ends, white space in attribute
//! values) are copied, once, into one side buffer.
//!
//! The arena is sized before the pass from the counts of
//! [`super::markup_scan`] (elements, attributes, text runs), so it is not
//! grown by doubling; the open elements are a stack of 4-byte indices. The
//! peak heap of a parse is thus a small multiple of the file: at most some
//! 12 bytes per byte for the densest markup (`<a/>x<a/>x...`, nested
//! `<b><b><b>...`), where the `roxmltree` DOM used before took some 72 bytes
//! per node and reserved as much again per `<` and `=`.
//!
//! Checked: well-formedness (names, matching end tags, one root element,
//! nothing but white space, comments and processing instructions around it,
//! quoted attribute values without `<`, no duplicate attribute, entity and
//! character references naming one of the five predefined entities or an XML
//! character, no `]]>` in text, no `--` in comments, characters XML allows,
//! the XML declaration only at the start, namespace prefixes declared in
//! scope). Not read: document type declarations (blanked by
//! [`super::xml_text`] in the prolog, refused anywhere else). Namespace URIs
//! are not resolved: elements are matched by their local name, attributes by
//! their unprefixed name, as the DAVE-ML reader always did.
//!
//! Errors are one line, "malformed XML: ..." at the line of the offending
//! markup; an element never closed is reported at the line where the
//! innermost unclosed element opened (the root's line when only
//! `</DAVEfunc>` is missing).

use std::borrow::Cow;
use std::collections::HashMap;
use std::ops::Range;

use super::{xml_text_counted, MAX_ATTRIBUTES};
use crate::error::AeroError;
use crate::text::{one_line, shown};

/// Longest text read: offsets are 32-bit.
pub(crate) const MAX_TEXT: usize = u32::MAX as usize - 1;

/// A text node's `decoded` start when its text is the input's, unchanged.
const RAW: u32 = u32::MAX;

/// One element or text run.
#[derive(Debug, Clone, Copy)]
struct NodeData {
    /// Byte range in the text: an element from its `<` to the end of its end
    /// tag; a text run from its first to past its last byte (CDATA markup
    /// and references included).
    start: u32,
    end: u32,
    /// Element: length of the (qualified) name, at `start + 1`. Text: 0.
    name_len: u32,
    /// Index past the last descendant (a text run: its own index + 1).
    subtree_end: u32,
    /// Element: first attribute and count. Text: the unescaped text's range
    /// in the side buffer, or ([`RAW`], 0) when the text is the input's.
    a: u32,
    b: u32,
}

/// One attribute (namespace declarations are not kept).
#[derive(Debug, Clone, Copy)]
struct AttrData {
    name: (u32, u32),
    /// Value range: in the text (inside the quotes), or in the side buffer.
    value: (u32, u32),
    decoded: bool,
}

/// A parsed document: the arena and the text it points into.
#[derive(Debug)]
pub(crate) struct Document<'t> {
    text: Cow<'t, str>,
    nodes: Vec<NodeData>,
    attrs: Vec<AttrData>,
    decoded: String,
}

/// Identity of a node within its document (hashable, 4 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct NodeId(u32);

/// A node of a [`Document`]: an element or a text run.
#[derive(Clone, Copy)]
pub(crate) struct Node<'a> {
    doc: &'a Document<'a>,
    id: u32,
}

impl std::fmt::Debug for Node<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_element() {
            write!(f, "Element({}, {:?})", self.tag_name(), self.range())
        } else {
            write!(f, "Text({:?})", self.text().unwrap_or(""))
        }
    }
}

impl<'t> Document<'t> {
    /// The root element (a document always has one: parsing refuses others).
    pub(crate) fn root_element(&self) -> Node<'_> {
        Node { doc: self, id: 0 }
    }

    /// Every node in document order, the root element first.
    pub(crate) fn descendants(&self) -> impl Iterator<Item = Node<'_>> {
        self.root_element().descendants()
    }

    /// Bytes of the arena and side buffer (capacity), for tests.
    #[cfg(test)]
    pub(crate) fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<NodeData>()
            + self.attrs.capacity() * std::mem::size_of::<AttrData>()
            + self.decoded.capacity()
    }

    fn slice(&self, r: (u32, u32)) -> &str {
        self.text.get(r.0 as usize..r.1 as usize).unwrap_or("")
    }
}

impl<'a> Node<'a> {
    fn data(self) -> &'a NodeData {
        &self.doc.nodes[self.id as usize]
    }

    pub(crate) fn id(self) -> NodeId {
        NodeId(self.id)
    }

    pub(crate) fn is_element(self) -> bool {
        self.data().name_len > 0
    }

    pub(crate) fn is_text(self) -> bool {
        self.data().name_len == 0
    }

    /// Byte range in the text (see [`NodeData`]).
    pub(crate) fn range(self) -> Range<usize> {
        let d = self.data();
        d.start as usize..d.end as usize
    }

    /// The local name of an element (after any `prefix:`); "" for text.
    pub(crate) fn tag_name(self) -> &'a str {
        let d = self.data();
        if d.name_len == 0 {
            return "";
        }
        let name = self.doc.slice((d.start + 1, d.start + 1 + d.name_len));
        match name.as_bytes().iter().rposition(|&c| c == b':') {
            Some(k) => name.get(k + 1..).unwrap_or(name),
            None => name,
        }
    }

    /// The value of the unprefixed attribute `name`, unescaped and normalized.
    pub(crate) fn attribute(self, name: &str) -> Option<&'a str> {
        let d = self.data();
        if d.name_len == 0 {
            return None;
        }
        let doc = self.doc;
        doc.attrs[d.a as usize..(d.a + d.b) as usize]
            .iter()
            .find(|a| doc.slice(a.name) == name)
            .map(|a| {
                if a.decoded {
                    doc.decoded
                        .get(a.value.0 as usize..a.value.1 as usize)
                        .unwrap_or("")
                } else {
                    doc.slice(a.value)
                }
            })
    }

    /// The text of a text node, unescaped; `None` for an element.
    pub(crate) fn text(self) -> Option<&'a str> {
        let d = self.data();
        if d.name_len > 0 {
            return None;
        }
        Some(if d.a == RAW {
            self.doc.slice((d.start, d.end))
        } else {
            self.doc
                .decoded
                .get(d.a as usize..d.b as usize)
                .unwrap_or("")
        })
    }

    /// The child nodes, in order.
    pub(crate) fn children(self) -> impl Iterator<Item = Node<'a>> {
        let doc = self.doc;
        let end = self.data().subtree_end;
        let mut next = self.id + 1;
        std::iter::from_fn(move || {
            if next >= end {
                return None;
            }
            let id = next;
            next = doc.nodes[id as usize].subtree_end;
            Some(Node { doc, id })
        })
    }

    /// This node and every node below it, in document order.
    pub(crate) fn descendants(self) -> impl Iterator<Item = Node<'a>> {
        let doc = self.doc;
        (self.id..self.data().subtree_end).map(move |id| Node { doc, id })
    }

    /// Whether `other` is below this node.
    pub(crate) fn contains(self, other: Node<'_>) -> bool {
        self.id < other.id && other.id < self.data().subtree_end
    }
}

/// What [`super::markup_scan`] counted: the arena is reserved from it.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Counts {
    /// Start and empty-element tags.
    pub elements: usize,
    /// `=` outside quotes in start tags (attributes and namespace declarations).
    pub attributes: usize,
    /// Runs of characters between markup (an upper bound of the text nodes).
    pub texts: usize,
}

/// Parse `text` (a whole file, named `file` in errors) into a [`Document`].
///
/// # Errors
/// A parse error naming the file and the line: as [`super::xml_text`], a text
/// of 4 GiB or more, or anything not well-formed (see the module).
pub(crate) fn parse_document<'t>(text: &'t str, file: &str) -> crate::Result<Document<'t>> {
    if text.len() > MAX_TEXT {
        return Err(AeroError::parse(
            file,
            1,
            format!(
                "the file is {} bytes; DAVE-ML files of 4 GiB or more are not read",
                text.len()
            ),
        ));
    }
    let (xml, counts) = xml_text_counted(text, file)?;
    let mut doc = Document {
        text: xml,
        nodes: Vec::new(),
        attrs: Vec::new(),
        decoded: String::new(),
    };
    let mut p = Parser {
        b: doc.text.as_bytes(),
        file,
        nodes: Vec::with_capacity(counts.elements + counts.texts),
        attrs: Vec::with_capacity(counts.attributes),
        decoded: String::new(),
        stack: Vec::new(),
        scope: Vec::new(),
        declared: HashMap::new(),
        names: Vec::new(),
        run: None,
        root_done: false,
    };
    p.run()?;
    let (nodes, attrs, decoded) = (p.nodes, p.attrs, p.decoded);
    doc.nodes = nodes;
    doc.attrs = attrs;
    doc.decoded = decoded;
    Ok(doc)
}

/// An open run of text (text, references, CDATA) in the current element.
#[derive(Clone, Copy)]
struct Run {
    node: u32,
    decode: bool,
}

struct Parser<'s> {
    b: &'s [u8],
    file: &'s str,
    nodes: Vec<NodeData>,
    attrs: Vec<AttrData>,
    decoded: String,
    /// Open elements (indices into `nodes`).
    stack: Vec<u32>,
    /// Namespace prefixes declared by open elements: (name range, depth).
    scope: Vec<(u32, u32, u32)>,
    /// Open declarations per prefix.
    declared: HashMap<&'s [u8], u32>,
    /// Raw attribute names of the tag being read (duplicate check).
    names: Vec<(u32, u32)>,
    run: Option<Run>,
    root_done: bool,
}

fn is_ws(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\n' | b'\r')
}

fn is_name_start(c: u8) -> bool {
    c.is_ascii_alphabetic() || c == b'_' || c == b':' || c >= 0x80
}

fn is_name_char(c: u8) -> bool {
    is_name_start(c) || c.is_ascii_digit() || c == b'-' || c == b'.'
}

/// The character of reference body `r` (`lt`, `#65`, `#x41`), if valid.
fn reference(r: &[u8]) -> Option<char> {
    let code = match r {
        b"lt" => return Some('<'),
        b"gt" => return Some('>'),
        b"amp" => return Some('&'),
        b"apos" => return Some('\''),
        b"quot" => return Some('"'),
        [b'#', b'x', hex @ ..] if !hex.is_empty() && hex.len() <= 8 => {
            u32::from_str_radix(std::str::from_utf8(hex).ok()?, 16).ok()?
        }
        [b'#', dec @ ..] if !dec.is_empty() && dec.len() <= 10 && dec[0] != b'+' => {
            std::str::from_utf8(dec).ok()?.parse::<u32>().ok()?
        }
        _ => return None,
    };
    // XML's Char production.
    let ok = matches!(code, 0x9 | 0xA | 0xD | 0x20..=0xD7FF | 0xE000..=0xFFFD | 0x10000..=0x10FFFF);
    if ok {
        char::from_u32(code)
    } else {
        None
    }
}

/// Check the body of the XML declaration (after `<?xml`, before `?>`):
/// `version="1.x"`, then optionally `encoding="..."` and `standalone="yes|no"`,
/// in this order, each after white space.
fn declaration(body: &[u8]) -> Result<(), String> {
    let mut rest = body;
    let mut seen = 0;
    loop {
        let ws = rest.iter().take_while(|&&c| is_ws(c)).count();
        rest = &rest[ws..];
        if rest.is_empty() {
            break;
        }
        if ws == 0 {
            return Err("white space must separate its parts".into());
        }
        let name_len = rest
            .iter()
            .take_while(|&&c| c.is_ascii_alphabetic())
            .count();
        let (name, after) = rest.split_at(name_len);
        let order = match name {
            b"version" => 1,
            b"encoding" => 2,
            b"standalone" => 3,
            _ => {
                return Err(format!(
                    "'{}' is not one of version, encoding, standalone",
                    shown(&String::from_utf8_lossy(&rest[..rest.len().min(40)]))
                ))
            }
        };
        if order <= seen || (seen == 0 && order != 1) {
            return Err("give version first, then encoding and standalone, each once".into());
        }
        seen = order;
        let name = String::from_utf8_lossy(name);
        let after = &after[after.iter().take_while(|&&c| is_ws(c)).count()..];
        let Some(after) = after.strip_prefix(b"=") else {
            return Err(format!("{name} has no '='"));
        };
        let after = &after[after.iter().take_while(|&&c| is_ws(c)).count()..];
        let Some((&q, after)) = after
            .split_first()
            .filter(|(q, _)| matches!(q, b'"' | b'\''))
        else {
            return Err(format!("the value of {name} is not in quotes"));
        };
        let Some(end) = after.iter().position(|&c| c == q) else {
            return Err(format!("the value of {name} is not closed"));
        };
        let v = &after[..end];
        let ok = match order {
            1 => v.len() > 2 && v.starts_with(b"1.") && v[2..].iter().all(u8::is_ascii_digit),
            2 => {
                v.first().is_some_and(u8::is_ascii_alphabetic)
                    && v.iter()
                        .all(|&c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-'))
            }
            _ => v == b"yes" || v == b"no",
        };
        if !ok {
            return Err(format!(
                "{name}=\"{}\" is not valid",
                shown(&String::from_utf8_lossy(v))
            ));
        }
        rest = &after[end + 1..];
    }
    if seen == 0 {
        return Err("it lacks version=\"1.0\"".into());
    }
    Ok(())
}

/// The body of the reference starting with the `&` at `at` in `s` (`amp`,
/// `#65`): the name characters and `#` up to a `;`; `None` when no `;` ends them.
fn ref_body(s: &[u8], at: usize) -> Option<&[u8]> {
    let rest = s.get(at + 1..)?;
    let len = rest.iter().position(|&c| !(is_name_char(c) || c == b'#'))?;
    (rest[len] == b';').then(|| &rest[..len])
}

impl<'s> Parser<'s> {
    fn line(&self, pos: usize) -> usize {
        1 + self.b[..pos.min(self.b.len())]
            .iter()
            .filter(|&&c| c == b'\n')
            .count()
    }

    fn text(&self, r: Range<usize>) -> &'s str {
        std::str::from_utf8(self.b.get(r).unwrap_or(b"")).unwrap_or("")
    }

    /// A "malformed XML" error at byte `pos`.
    fn err(&self, pos: usize, msg: impl AsRef<str>) -> AeroError {
        AeroError::parse(
            self.file,
            self.line(pos),
            one_line(&format!("malformed XML: {}", msg.as_ref())),
        )
    }

    fn find(&self, from: usize, pat: &[u8]) -> Option<usize> {
        super::find(self.b, from, pat)
    }

    fn run(&mut self) -> crate::Result<()> {
        let b = self.b;
        // Characters XML does not allow: controls, U+FFFE and U+FFFF (a
        // simple predicate first, so the scan of the whole text stays fast).
        let mut from = 0;
        while let Some(k) = b[from..]
            .iter()
            .position(|&c| (c < 0x20 && !matches!(c, b'\t' | b'\n' | b'\r')) || c == 0xEF)
        {
            let k = from + k;
            if b[k] != 0xEF {
                return Err(self.err(
                    k,
                    format!(
                        "the control character U+{:04X} is not allowed in XML; remove it",
                        b[k]
                    ),
                ));
            }
            if b.get(k + 1) == Some(&0xBF) && matches!(b.get(k + 2), Some(0xBE | 0xBF)) {
                return Err(self.err(
                    k,
                    "the non-character U+FFFE or U+FFFF is not allowed in XML; remove it",
                ));
            }
            from = k + 1;
        }
        let decl_at = usize::from(b.starts_with(&[0xEF, 0xBB, 0xBF])) * 3;
        let mut pos = decl_at;
        loop {
            let Some(k) = b[pos..].iter().position(|&c| c == b'<') else {
                self.chars(pos, b.len())?;
                break;
            };
            if k > 0 {
                self.chars(pos, pos + k)?;
            }
            pos += k;
            let rest = &b[pos..];
            pos = if rest.starts_with(b"<!--") {
                self.comment(pos)?
            } else if rest.starts_with(b"<![CDATA[") {
                self.cdata(pos)?
            } else if rest.starts_with(b"<?") {
                self.pi(pos, decl_at)?
            } else if rest.starts_with(b"<!DOCTYPE") {
                return Err(AeroError::parse(
                    self.file,
                    self.line(pos),
                    "a <!DOCTYPE> declaration where the XML prolog cannot hold one; put it before \
                     the root element, after the XML declaration and comments",
                ));
            } else if rest.starts_with(b"<!") {
                return Err(self.err(
                    pos,
                    "unknown markup '<!'; only comments <!-- -->, <![CDATA[ ]]> and one \
                     <!DOCTYPE> before the root element are XML",
                ));
            } else if rest.starts_with(b"</") {
                self.end_tag(pos)?
            } else {
                self.start_tag(pos)?
            };
        }
        self.close_run();
        if let Some(&open) = self.stack.last() {
            let d = self.nodes[open as usize];
            let name = self.text(d.start as usize + 1..(d.start + 1 + d.name_len) as usize);
            return Err(self.err(
                d.start as usize,
                format!(
                    "<{}> is opened here but never closed; close it with </{}>",
                    shown(name),
                    shown(name)
                ),
            ));
        }
        if !self.root_done {
            return Err(self.err(
                b.len(),
                "the document has no root element; a DAVE-ML file holds one <DAVEfunc> element",
            ));
        }
        Ok(())
    }

    /// Character data `start..end` (no markup).
    fn chars(&mut self, start: usize, end: usize) -> crate::Result<()> {
        let s = &self.b[start..end];
        if self.stack.is_empty() {
            if let Some(k) = s.iter().position(|&c| !is_ws(c)) {
                let what = if self.root_done { "after" } else { "before" };
                return Err(self.err(
                    start + k,
                    format!(
                        "text {what} the root element; only white space, comments and \
                         processing instructions may stand outside it"
                    ),
                ));
            }
            return Ok(());
        }
        let mut decode = false;
        let mut i = 0;
        while let Some(k) = s[i..]
            .iter()
            .position(|&c| matches!(c, b'&' | b'\r' | b']'))
        {
            let at = i + k;
            match s[at] {
                b'&' => {
                    let body = ref_body(s, at);
                    if body.and_then(reference).is_none() {
                        let shown_ref = match body {
                            Some(r) => format!("'&{};'", shown(&String::from_utf8_lossy(r))),
                            None => "'&'".to_string(),
                        };
                        let what = match body {
                            Some(r) if r.first() == Some(&b'#') => {
                                "is not a character XML allows".to_string()
                            }
                            Some(r) => format!(
                                "is an unknown entity reference '{}': only &lt; &gt; &amp; \
                                 &apos; &quot; and character references are read",
                                shown(&String::from_utf8_lossy(r))
                            ),
                            None => "does not start a reference '&name;'; write a literal '&' \
                                     as &amp;"
                                .into(),
                        };
                        return Err(self.err(start + at, format!("{shown_ref} {what}")));
                    }
                    decode = true;
                    i = at + 1;
                }
                b'\r' => {
                    decode = true;
                    i = at + 1;
                }
                b']' => {
                    if s[at..].starts_with(b"]]>") {
                        return Err(
                            self.err(start + at, "']]>' is not allowed in text; write ']]&gt;'")
                        );
                    }
                    i = at + 1;
                }
                _ => i = at + 1,
            }
        }
        self.extend_run(start, end, decode);
        Ok(())
    }

    /// Add `start..end` to the open text run, or open one.
    fn extend_run(&mut self, start: usize, end: usize, decode: bool) {
        match &mut self.run {
            Some(r) => {
                r.decode |= decode;
                self.nodes[r.node as usize].end = end as u32;
            }
            None => {
                let id = self.nodes.len() as u32;
                self.nodes.push(NodeData {
                    start: start as u32,
                    end: end as u32,
                    name_len: 0,
                    subtree_end: id + 1,
                    a: RAW,
                    b: 0,
                });
                self.run = Some(Run { node: id, decode });
            }
        }
    }

    /// Close the open text run, unescaping it if needed.
    fn close_run(&mut self) {
        let Some(run) = self.run.take() else { return };
        if !run.decode {
            return;
        }
        let n = self.nodes[run.node as usize];
        let s = &self.b[n.start as usize..n.end as usize];
        let from = self.decoded.len();
        let mut i = 0;
        while i < s.len() {
            let k = s[i..]
                .iter()
                .position(|&c| matches!(c, b'&' | b'\r' | b'<'))
                .map_or(s.len(), |k| i + k);
            self.decoded
                .push_str(std::str::from_utf8(&s[i..k]).unwrap_or(""));
            if k == s.len() {
                break;
            }
            match s[k] {
                b'&' => {
                    let e = s[k..]
                        .iter()
                        .position(|&c| c == b';')
                        .map_or(s.len(), |e| k + e);
                    if let Some(c) = reference(&s[(k + 1).min(e)..e]) {
                        self.decoded.push(c);
                    }
                    i = e + 1;
                }
                b'\r' => {
                    self.decoded.push('\n');
                    i = if s.get(k + 1) == Some(&b'\n') {
                        k + 2
                    } else {
                        k + 1
                    };
                }
                _ => {
                    // <![CDATA[ ... ]]>: its content as is, line ends normalized.
                    let body = k + 9;
                    let e = super::find(s, body, b"]]>").unwrap_or(s.len());
                    let mut c = s.get(body..e).unwrap_or(b"");
                    while let Some(r) = c.iter().position(|&x| x == b'\r') {
                        self.decoded
                            .push_str(std::str::from_utf8(&c[..r]).unwrap_or(""));
                        self.decoded.push('\n');
                        c = if c.get(r + 1) == Some(&b'\n') {
                            &c[r + 2..]
                        } else {
                            &c[r + 1..]
                        };
                    }
                    self.decoded.push_str(std::str::from_utf8(c).unwrap_or(""));
                    i = e + 3;
                }
            }
        }
        let node = &mut self.nodes[run.node as usize];
        node.a = from as u32;
        node.b = self.decoded.len() as u32;
    }

    fn comment(&mut self, pos: usize) -> crate::Result<usize> {
        let Some(e) = self.find(pos + 4, b"-->") else {
            return Err(self.err(pos, "a comment '<!--' is not closed; end it with '-->'"));
        };
        let body = &self.b[pos + 4..e];
        if let Some(k) = super::find(body, 0, b"--") {
            return Err(self.err(
                pos + 4 + k,
                "'--' inside a comment; XML comments cannot hold it",
            ));
        }
        if body.ends_with(b"-") {
            return Err(self.err(
                e,
                "a comment ends with '--->'; XML comments cannot end in '-'",
            ));
        }
        self.close_run();
        Ok(e + 3)
    }

    fn cdata(&mut self, pos: usize) -> crate::Result<usize> {
        let Some(e) = self.find(pos + 9, b"]]>") else {
            return Err(self.err(
                pos,
                "a '<![CDATA[' section is not closed; end it with ']]>'",
            ));
        };
        if self.stack.is_empty() {
            return Err(self.err(pos, "a CDATA section outside the root element"));
        }
        self.extend_run(pos, e + 3, true);
        Ok(e + 3)
    }

    fn pi(&mut self, pos: usize, decl_at: usize) -> crate::Result<usize> {
        let Some(e) = self.find(pos + 2, b"?>") else {
            return Err(self.err(
                pos,
                "a processing instruction '<?' is not closed; end it with '?>'",
            ));
        };
        let target_end = (pos + 2..e)
            .find(|&k| !is_name_char(self.b[k]))
            .unwrap_or(e);
        let target = &self.b[pos + 2..target_end];
        if target.is_empty()
            || !is_name_start(target[0])
            || (target_end < e && !is_ws(self.b[target_end]))
        {
            return Err(self.err(
                pos,
                "a processing instruction '<?' without a valid target name",
            ));
        }
        if target.eq_ignore_ascii_case(b"xml") {
            if pos != decl_at || target != b"xml" {
                return Err(self.err(
                    pos,
                    "an XML declaration '<?xml ...?>' that is not at the very start of the file \
                     (or not in lower case)",
                ));
            }
            if let Err(msg) = declaration(&self.b[target_end..e]) {
                return Err(self.err(pos, format!("the XML declaration: {msg}")));
            }
        }
        self.close_run();
        Ok(e + 2)
    }

    /// The end of the name starting at `pos`.
    fn name(&self, pos: usize) -> crate::Result<usize> {
        if !self.b.get(pos).is_some_and(|&c| is_name_start(c)) {
            let found = match self.b.get(pos) {
                Some(&c) if c.is_ascii_graphic() => format!("'{}'", char::from(c)),
                Some(&c) if is_ws(c) => "white space".to_string(),
                Some(_) => "a character".to_string(),
                None => "the end of the file".to_string(),
            };
            return Err(self.err(pos, format!("expected a name, found {found}")));
        }
        let end = (pos + 1..self.b.len())
            .find(|&k| !is_name_char(self.b[k]))
            .unwrap_or(self.b.len());
        Ok(end)
    }

    /// The prefix of qualified name `start..end`, checked (at most one ':',
    /// not first or last).
    fn prefix(&self, start: usize, end: usize) -> crate::Result<Option<&'s [u8]>> {
        let n = &self.b[start..end];
        let Some(k) = n.iter().position(|&c| c == b':') else {
            return Ok(None);
        };
        if k == 0 || k + 1 == n.len() || n[k + 1..].contains(&b':') {
            return Err(self.err(
                start,
                format!(
                    "'{}' is not a valid qualified name (prefix:name)",
                    shown(self.text(start..end))
                ),
            ));
        }
        Ok(Some(&self.b[start..start + k]))
    }

    fn check_prefix(&self, start: usize, end: usize) -> crate::Result<()> {
        if let Some(p) = self.prefix(start, end)? {
            if p != b"xml" && self.declared.get(p).is_none_or(|&c| c == 0) {
                return Err(self.err(
                    start,
                    format!(
                        "'{}' uses the namespace prefix '{}', which is not declared; add \
                         xmlns:{}=\"...\" to it or an enclosing element",
                        shown(self.text(start..end)),
                        shown(&String::from_utf8_lossy(p)),
                        shown(&String::from_utf8_lossy(p))
                    ),
                ));
            }
        }
        Ok(())
    }

    fn end_tag(&mut self, pos: usize) -> crate::Result<usize> {
        let name_end = self.name(pos + 2)?;
        let mut k = name_end;
        while self.b.get(k).is_some_and(|&c| is_ws(c)) {
            k += 1;
        }
        if self.b.get(k) != Some(&b'>') {
            return Err(self.err(
                pos,
                format!(
                    "the end tag </{}> is not closed by '>'",
                    shown(self.text(pos + 2..name_end))
                ),
            ));
        }
        let name = &self.b[pos + 2..name_end];
        let Some(&open) = self.stack.last() else {
            return Err(self.err(
                pos,
                format!(
                    "the end tag </{}> closes no open element",
                    shown(self.text(pos + 2..name_end))
                ),
            ));
        };
        let d = self.nodes[open as usize];
        let open_name = &self.b[d.start as usize + 1..(d.start + 1 + d.name_len) as usize];
        if name != open_name {
            let open_name = self.text(d.start as usize + 1..(d.start + 1 + d.name_len) as usize);
            return Err(self.err(
                pos,
                format!(
                    "the end tag </{}> does not match <{}> (line {}); close it with </{}>",
                    shown(self.text(pos + 2..name_end)),
                    shown(open_name),
                    self.line(d.start as usize),
                    shown(open_name)
                ),
            ));
        }
        self.close_run();
        let depth = self.stack.len() as u32;
        self.stack.pop();
        let total = self.nodes.len() as u32;
        let node = &mut self.nodes[open as usize];
        node.end = (k + 1) as u32;
        node.subtree_end = total;
        self.end_scope(depth);
        if self.stack.is_empty() {
            self.root_done = true;
        }
        Ok(k + 1)
    }

    /// Forget the namespace declarations of the element at `depth`.
    fn end_scope(&mut self, depth: u32) {
        while let Some(&(s, e, d)) = self.scope.last() {
            if d < depth {
                break;
            }
            self.scope.pop();
            if let Some(c) = self.declared.get_mut(&self.b[s as usize..e as usize]) {
                *c -= 1;
            }
        }
    }

    fn start_tag(&mut self, pos: usize) -> crate::Result<usize> {
        let b = self.b;
        let name_end = self.name(pos + 1)?;
        let tag = |p: &Self| shown(p.text(pos + 1..name_end));
        if self.stack.is_empty() && self.root_done {
            return Err(self.err(
                pos,
                format!(
                    "a second root element <{}>; an XML document has one root element",
                    tag(self)
                ),
            ));
        }
        self.close_run();
        let depth = self.stack.len() as u32 + 1;
        let first_attr = self.attrs.len();
        self.names.clear();
        let mut k = name_end;
        let empty = loop {
            let ws = k;
            while b.get(k).is_some_and(|&c| is_ws(c)) {
                k += 1;
            }
            match b.get(k) {
                None => {
                    return Err(self.err(
                        pos,
                        format!("the tag <{}> is not closed by '>' or '/>'", tag(self)),
                    ))
                }
                Some(b'>') => break false,
                Some(b'/') if b.get(k + 1) == Some(&b'>') => break true,
                Some(b'/') => {
                    return Err(self.err(
                        k,
                        format!("'/' in the tag <{}> not followed by '>'", tag(self)),
                    ))
                }
                Some(_) if k == ws => {
                    return Err(self.err(
                        k,
                        format!(
                            "the tag <{}> needs white space before each attribute",
                            tag(self)
                        ),
                    ))
                }
                Some(_) => {}
            }
            // An attribute: name = "value".
            let an = k;
            let an_end = self.name(an)?;
            k = an_end;
            while b.get(k).is_some_and(|&c| is_ws(c)) {
                k += 1;
            }
            if b.get(k) != Some(&b'=') {
                return Err(self.err(
                    an,
                    format!(
                        "the attribute '{}' of <{}> has no '=\"value\"'",
                        shown(self.text(an..an_end)),
                        tag(self)
                    ),
                ));
            }
            k += 1;
            while b.get(k).is_some_and(|&c| is_ws(c)) {
                k += 1;
            }
            let quote = match b.get(k) {
                Some(&q @ (b'"' | b'\'')) => q,
                _ => {
                    return Err(self.err(
                        an,
                        format!(
                            "the value of attribute '{}' of <{}> is not in quotes",
                            shown(self.text(an..an_end)),
                            tag(self)
                        ),
                    ))
                }
            };
            let vs = k + 1;
            let Some(ve) = b[vs..].iter().position(|&c| c == quote).map(|e| vs + e) else {
                return Err(self.err(
                    an,
                    format!(
                        "the value of attribute '{}' of <{}> is not closed by {}",
                        shown(self.text(an..an_end)),
                        tag(self),
                        char::from(quote)
                    ),
                ));
            };
            k = ve + 1;
            if self.names.len() >= MAX_ATTRIBUTES {
                return Err(super::too_many_attributes(
                    self.file,
                    self.line(pos),
                    self.text(pos + 1..name_end),
                    self.names.len() + 1,
                ));
            }
            let aname = &b[an..an_end];
            if self
                .names
                .iter()
                .any(|&(s, e)| &b[s as usize..e as usize] == aname)
            {
                return Err(self.err(
                    an,
                    format!(
                        "<{}> has the attribute '{}' twice",
                        tag(self),
                        shown(self.text(an..an_end))
                    ),
                ));
            }
            self.names.push((an as u32, an_end as u32));
            let value = self.value(an, an_end, vs, ve)?;
            if aname == b"xmlns" {
                continue;
            }
            if let Some(p) = aname.strip_prefix(b"xmlns:") {
                if p.contains(&b':') || p == b"xmlns" {
                    return Err(self.err(
                        an,
                        format!(
                            "'xmlns:{}' cannot be declared",
                            shown(&String::from_utf8_lossy(p))
                        ),
                    ));
                }
                if vs == ve {
                    return Err(self.err(
                        an,
                        format!(
                            "the namespace prefix '{}' is declared with an empty URI",
                            shown(&String::from_utf8_lossy(p))
                        ),
                    ));
                }
                let p0 = an + 6;
                self.scope.push((p0 as u32, an_end as u32, depth));
                *self.declared.entry(&b[p0..an_end]).or_insert(0) += 1;
                continue;
            }
            self.attrs.push(AttrData {
                name: (an as u32, an_end as u32),
                value: value.0,
                decoded: value.1,
            });
        };
        // Prefixes resolve against the declarations of this tag too.
        self.check_prefix(pos + 1, name_end)?;
        for i in first_attr..self.attrs.len() {
            let (s, e) = self.attrs[i].name;
            self.check_prefix(s as usize, e as usize)?;
        }
        let id = self.nodes.len() as u32;
        let end = if empty { k + 2 } else { k + 1 };
        self.nodes.push(NodeData {
            start: pos as u32,
            end: end as u32,
            name_len: (name_end - pos - 1) as u32,
            subtree_end: id + 1,
            a: first_attr as u32,
            b: (self.attrs.len() - first_attr) as u32,
        });
        if empty {
            self.end_scope(depth);
            if self.stack.is_empty() {
                self.root_done = true;
            }
        } else {
            self.stack.push(id);
        }
        Ok(end)
    }

    /// Check attribute value `vs..ve` (of the attribute named `an..an_end`)
    /// and unescape it if needed: its range and whether it is in the side buffer.
    fn value(
        &mut self,
        an: usize,
        an_end: usize,
        vs: usize,
        ve: usize,
    ) -> crate::Result<((u32, u32), bool)> {
        let v = &self.b[vs..ve];
        if !v
            .iter()
            .any(|&c| matches!(c, b'&' | b'<' | b'\t' | b'\n' | b'\r'))
        {
            return Ok(((vs as u32, ve as u32), false));
        }
        if let Some(k) = v.iter().position(|&c| c == b'<') {
            return Err(self.err(
                vs + k,
                format!(
                    "'<' in the value of attribute '{}'; write it as &lt;",
                    shown(self.text(an..an_end))
                ),
            ));
        }
        let from = self.decoded.len();
        let mut i = 0;
        while i < v.len() {
            let k = v[i..]
                .iter()
                .position(|&c| matches!(c, b'&' | b'\t' | b'\n' | b'\r'))
                .map_or(v.len(), |k| i + k);
            self.decoded
                .push_str(std::str::from_utf8(&v[i..k]).unwrap_or(""));
            if k == v.len() {
                break;
            }
            if v[k] == b'&' {
                let body = ref_body(v, k);
                let c = body.and_then(reference);
                let (Some(body), Some(c)) = (body, c) else {
                    let r = body.map_or_else(
                        || "'&'".to_string(),
                        |r| format!("'&{};'", shown(&String::from_utf8_lossy(r))),
                    );
                    return Err(self.err(
                        vs + k,
                        format!(
                            "{r} in the value of attribute '{}' is not a character or \
                             predefined entity reference (&lt; &gt; &amp; &apos; &quot;)",
                            shown(self.text(an..an_end))
                        ),
                    ));
                };
                self.decoded.push(c);
                i = k + body.len() + 2;
            } else {
                // Attribute-value normalization: a line end or tab is a space.
                self.decoded.push(' ');
                i = if v[k] == b'\r' && v.get(k + 1) == Some(&b'\n') {
                    k + 2
                } else {
                    k + 1
                };
            }
        }
        Ok(((from as u32, self.decoded.len() as u32), true))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc(text: &str) -> Document<'_> {
        parse_document(text, "t.xml").unwrap_or_else(|e| panic!("{e}"))
    }

    fn refused(text: &str) -> String {
        let e = parse_document(text, "t.xml").expect_err("malformed");
        let msg = e.to_string();
        assert!(msg.starts_with("t.xml:") && !msg.contains('\n'), "{msg}");
        msg
    }

    #[test]
    fn tree_names_attributes_and_text_as_written() {
        let text = "<?xml version=\"1.0\"?>\n<!-- c -->\n<r xmlns=\"u\" xmlns:m=\"v\" a=\"1\" b='x &amp; &#65;&#x42;\t\r\ny'>\
                    t1<m:c k=\"&lt;&gt;&quot;&apos;\"/>t2<!--x-->t3<![CDATA[<&>]]>t4&#10;\r\n<d/></r>\n";
        let d = doc(text);
        let r = d.root_element();
        assert_eq!(r.tag_name(), "r");
        assert_eq!(r.range(), text.find("<r ").unwrap_or(0)..text.len() - 1);
        assert_eq!(r.attribute("a"), Some("1"));
        assert_eq!(r.attribute("b"), Some("x & AB  y"));
        assert_eq!(r.attribute("xmlns"), None);
        assert_eq!(r.attribute("c"), None);
        let kids: Vec<Node> = r.children().collect();
        let shape: Vec<(bool, &str, Option<&str>)> = kids
            .iter()
            .map(|n| (n.is_element(), n.tag_name(), n.text()))
            .collect();
        assert_eq!(
            shape,
            vec![
                (false, "", Some("t1")),
                (true, "c", None),
                (false, "", Some("t2")),
                (false, "", Some("t3<&>t4\n\n")),
                (true, "d", None),
            ]
        );
        assert_eq!(kids[1].attribute("k"), Some("<>\"'"));
        assert_eq!(r.descendants().count(), 6);
        assert!(r.contains(kids[4]) && !kids[1].contains(kids[4]));
        assert_eq!(&text[kids[1].range()], "<m:c k=\"&lt;&gt;&quot;&apos;\"/>");
    }

    #[test]
    fn nesting_is_read_without_recursion_and_siblings_skip_subtrees() {
        let n = 50_000;
        let text = format!("<r>{}x{}<z/></r>", "<b>".repeat(n), "</b>".repeat(n));
        let d = doc(&text);
        let kids: Vec<&str> = d.root_element().children().map(|k| k.tag_name()).collect();
        assert_eq!(kids, ["b", "z"]);
        assert_eq!(d.descendants().count(), n + 3);
    }

    #[test]
    fn malformed_documents_are_one_line_with_the_line() {
        for (text, want) in [
            ("<r>\n<a>\n</b></r>", "t.xml:3: malformed XML: the end tag </b> does not match <a> (line 2)"),
            ("<r>\n<a>", "t.xml:2: malformed XML: <a> is opened here but never closed"),
            ("\n<r a=\"1\" a=\"2\"/>", "t.xml:2: malformed XML: <r> has the attribute 'a' twice"),
            ("<r/><s/>", "t.xml:1: malformed XML: a second root element <s>"),
            ("<r/>x", "t.xml:1: malformed XML: text after the root element"),
            ("x<r/>", "t.xml:1: malformed XML: text before the root element"),
            ("", "t.xml:1: malformed XML: the document has no root element"),
            ("<!-- only -->\n", "t.xml:2: malformed XML: the document has no root element"),
            ("<r>&nope;</r>", "t.xml:1: malformed XML: '&nope;' is an unknown entity reference 'nope'"),
            ("<r>&#0;</r>", "t.xml:1: malformed XML: '&#0;' is not a character XML allows"),
            ("<r>a & b;</r>", "t.xml:1: malformed XML: '&' does not start a reference"),
            ("<r>a &b c;</r>", "t.xml:1: malformed XML: '&' does not start a reference"),
            ("<r a=\"x & y;\"/>", "t.xml:1: malformed XML: '&' in the value of attribute 'a'"),
            ("<r a=\"<\"/>", "t.xml:1: malformed XML: '<' in the value of attribute 'a'"),
            ("<r a=\"&x;\"/>", "t.xml:1: malformed XML: '&x;' in the value of attribute 'a'"),
            ("<r a=1/>", "t.xml:1: malformed XML: the value of attribute 'a' of <r> is not in quotes"),
            ("<r a/>", "t.xml:1: malformed XML: the attribute 'a' of <r> has no '=\"value\"'"),
            ("<r a=\"1\"b=\"2\"/>", "t.xml:1: malformed XML: the tag <r> needs white space"),
            ("<r>]]></r>", "t.xml:1: malformed XML: ']]>' is not allowed in text"),
            ("<r><!-- a -- b --></r>", "t.xml:1: malformed XML: '--' inside a comment"),
            ("<r><!-- a </r>", "t.xml:1: malformed XML: a comment '<!--' is not closed"),
            ("<r><![CDATA[ a </r>", "t.xml:1: malformed XML: a '<![CDATA[' section is not closed"),
            ("<r>\n<?xml version=\"1.0\"?></r>", "t.xml:2: malformed XML: an XML declaration"),
            ("<?xml?><r/>", "t.xml:1: malformed XML: the XML declaration: it lacks version"),
            ("<?xml version=\"2.0\"?><r/>", "t.xml:1: malformed XML: the XML declaration: version=\"2.0\" is not valid"),
            ("<?xml version=\"1.0\" standalonu=\"no\"?><r/>", "t.xml:1: malformed XML: the XML declaration: 'standalonu"),
            ("<?xml version=\"1.0\" standalone=\"?>\n<r/>", "t.xml:1: malformed XML: the XML declaration: the value of standalone is not closed"),
            ("<?xml v<b>ersion=\"1.0\"?><r/>", "t.xml:1: malformed XML: the XML declaration: 'v<b>ersion"),
            ("<?xml encoding=\"UTF-8\" version=\"1.0\"?><r/>", "t.xml:1: malformed XML: the XML declaration: give version first"),
            ("<?xml version=\"1.0\"encoding=\"UTF-8\"?><r/>", "t.xml:1: malformed XML: the XML declaration: white space"),
            ("<?xml`version=\"1.0\"?><r/>", "t.xml:1: malformed XML: a processing instruction '<?' without a valid target"),
            ("<r><p:a/></r>", "t.xml:1: malformed XML: 'p:a' uses the namespace prefix 'p', which is not declared"),
            ("<r><a p:x=\"1\"/></r>", "t.xml:1: malformed XML: 'p:x' uses the namespace prefix 'p'"),
            ("<r><a:b:c xmlns:a=\"u\"/></r>", "t.xml:1: malformed XML: 'a:b:c' is not a valid qualified name"),
            ("<r>\u{1}</r>", "t.xml:1: malformed XML: the control character U+0001"),
            ("<r>\u{FFFE}</r>", "t.xml:1: malformed XML: the non-character U+FFFE"),
            ("<1/>", "t.xml:1: malformed XML: expected a name, found '1'"),
            ("<r></ r>", "t.xml:1: malformed XML: expected a name, found white space"),
            ("<r></r x>", "t.xml:1: malformed XML: the end tag </r> is not closed by '>'"),
            ("<r><![CDATA[x]]></r><![CDATA[y]]>", "t.xml:1: malformed XML: a CDATA section outside the root element"),
            ("<r><!x></r>", "t.xml:1: malformed XML: unknown markup '<!'"),
            ("<r></r></r>", "t.xml:1: malformed XML: the end tag </r> closes no open element"),
            ("<r", "t.xml:1: malformed XML: the tag <r> is not closed"),
        ] {
            let msg = refused(text);
            assert!(msg.starts_with(want), "{text:?}: {msg}");
        }
        doc("\u{FEFF}<?xml version='1.1' encoding=\"ISO-8859-1\" standalone='no' ?>\n<r/>");
        doc("<?xml version=\"1.0\"?><?xml-stylesheet href=\"a\"?><r/>");
        // Declared prefixes are in scope below their element only.
        doc("<r xmlns:p=\"u\"><p:a p:x=\"1\" xml:lang=\"en\"/></r>");
        doc("<r><a xmlns:p=\"u\" p:x=\"1\"><p:b/></a></r>");
        let msg = refused("<r><a xmlns:p=\"u\"/><p:b/></r>");
        assert!(msg.contains("prefix 'p', which is not declared"), "{msg}");
    }

    #[test]
    fn the_arena_is_reserved_from_the_markup_counts_not_grown() {
        // Dense markup: every capacity is the exact need or within the counts.
        for text in [
            format!("<r>{}</r>", "<a/>x".repeat(10_000)),
            format!("<r>{}</r>", "<a b=\"\" c=\"\"/>".repeat(10_000)),
            format!("<r>{}{}</r>", "<b>".repeat(10_000), "</b>".repeat(10_000)),
            format!("<r>{}</r>", "<!---->x".repeat(10_000)),
            format!("<r>{}</r>", "<![CDATA[]]>x".repeat(10_000)),
            format!("<r>y{}</r>", "<![CDATA[a]]>".repeat(10_000)),
        ] {
            let d = doc(&text);
            assert_eq!(d.nodes.capacity(), d.nodes.len(), "{}", &text[..20]);
            assert_eq!(d.attrs.capacity(), d.attrs.len(), "{}", &text[..20]);
            assert!(
                d.heap_bytes() <= 10 * text.len(),
                "{} bytes",
                d.heap_bytes()
            );
        }
    }
}
