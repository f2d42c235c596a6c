//! SOAP envelopes (ONVIF Core 5.1: SOAP 1.2, and SOAP 1.1 as older clients
//! send it): a request read with quick-xml into a small element tree
//! (namespaces resolved, depth and size bounded), and responses and faults
//! written in the request's own SOAP version with the ONVIF namespace
//! prefixes.

use quick_xml::escape::escape;
use quick_xml::events::{BytesStart, Event};
use quick_xml::name::ResolveResult;
use quick_xml::reader::NsReader;

pub const NS_SOAP: &str = "http://www.w3.org/2003/05/soap-envelope";
/// SOAP 1.1's envelope namespace (W3C Note "SOAP 1.1", 4.1.2).
pub const NS_SOAP11: &str = "http://schemas.xmlsoap.org/soap/envelope/";
pub const NS_DEVICE: &str = "http://www.onvif.org/ver10/device/wsdl";
pub const NS_MEDIA: &str = "http://www.onvif.org/ver10/media/wsdl";
pub const NS_PTZ: &str = "http://www.onvif.org/ver20/ptz/wsdl";

/// Deepest element nesting read; an ONVIF request is a few levels deep.
const MAX_DEPTH: usize = 32;
/// Most elements read from one document.
const MAX_ELEMENTS: usize = 4096;

/// One element: its namespace and local name, attributes (local names),
/// text and children.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Element {
    pub ns: String,
    pub name: String,
    pub attrs: Vec<(String, String)>,
    pub text: String,
    pub children: Vec<Element>,
}

impl Element {
    /// The first child named `name` (local name).
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }

    /// The child at the end of `path` of local names.
    pub fn path(&self, path: &[&str]) -> Option<&Element> {
        path.iter().try_fold(self, |e, name| e.child(name))
    }

    /// An attribute by local name.
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| k == name).map(|(_, v)| v.as_str())
    }

    /// The trimmed text of the child at `path`.
    pub fn text_at(&self, path: &[&str]) -> Option<&str> {
        self.path(path).map(|e| e.text.trim())
    }
}

/// Parses a whole document into its root element.
pub fn parse(xml: &[u8]) -> Result<Element, String> {
    let text = std::str::from_utf8(xml).map_err(|e| format!("not UTF-8: {e}"))?;
    let mut reader = NsReader::from_str(text);
    reader.config_mut().trim_text(false);
    let mut stack: Vec<Element> = Vec::new();
    let mut root = None;
    let mut count = 0usize;
    loop {
        let position = reader.buffer_position();
        let (resolved, event) = reader
            .read_resolved_event()
            .map_err(|e| format!("malformed XML after byte {position}: {e}"))?;
        let empty = matches!(event, Event::Empty(_));
        match event {
            Event::Start(start) | Event::Empty(start) if root.is_none() => {
                count += 1;
                if count > MAX_ELEMENTS || stack.len() >= MAX_DEPTH {
                    return Err(format!("more than {MAX_ELEMENTS} elements or {MAX_DEPTH} levels"));
                }
                let element = element_of(resolved, &start)?;
                if empty {
                    close(&mut stack, &mut root, element);
                } else {
                    stack.push(element);
                }
            }
            Event::Start(_) | Event::Empty(_) => return Err("content after the root element".into()),
            Event::End(_) => {
                let element = stack.pop().ok_or("an end tag without its start")?;
                close(&mut stack, &mut root, element);
            }
            Event::Text(t) => {
                if let Some(top) = stack.last_mut() {
                    let t = t.decode().map_err(|e| format!("malformed text: {e}"))?;
                    let t = quick_xml::escape::unescape(&t).map_err(|e| format!("malformed text: {e}"))?;
                    top.text.push_str(&t);
                }
            }
            Event::CData(t) => {
                if let Some(top) = stack.last_mut() {
                    top.text.push_str(&String::from_utf8_lossy(&t));
                }
            }
            Event::GeneralRef(r) => {
                if let Some(top) = stack.last_mut() {
                    let name = r.decode().map_err(|e| format!("malformed reference: {e}"))?;
                    let text = quick_xml::escape::unescape(&format!("&{name};"))
                        .map_err(|e| format!("unknown entity &{name};: {e}"))?
                        .into_owned();
                    top.text.push_str(&text);
                }
            }
            Event::DocType(_) => return Err("a DOCTYPE is not accepted".into()),
            Event::Eof => break,
            _ => {}
        }
    }
    if !stack.is_empty() {
        return Err("the document ends inside an element".into());
    }
    root.ok_or_else(|| "no root element".into())
}

fn element_of(resolved: ResolveResult<'_>, start: &BytesStart<'_>) -> Result<Element, String> {
    let ns = match resolved {
        ResolveResult::Bound(ns) => String::from_utf8_lossy(ns.as_ref()).into_owned(),
        ResolveResult::Unbound => String::new(),
        ResolveResult::Unknown(p) => {
            return Err(format!("undeclared namespace prefix {:?}", String::from_utf8_lossy(&p)));
        }
    };
    let mut element = Element {
        ns,
        name: String::from_utf8_lossy(start.local_name().as_ref()).into_owned(),
        ..Element::default()
    };
    for attr in start.attributes() {
        let attr = attr.map_err(|e| format!("malformed attribute: {e}"))?;
        let value = attr
            .unescape_value()
            .map_err(|e| format!("malformed attribute value: {e}"))?;
        element.attrs.push((
            String::from_utf8_lossy(attr.key.local_name().as_ref()).into_owned(),
            value.into_owned(),
        ));
    }
    Ok(element)
}

fn close(stack: &mut [Element], root: &mut Option<Element>, element: Element) {
    match stack.last_mut() {
        Some(parent) => parent.children.push(element),
        None => *root = Some(element),
    }
}

/// The SOAP version of a request, which its answer is written in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Version {
    /// SOAP 1.1: `text/xml`, faults as `faultcode` and `faultstring`, and
    /// every fault with HTTP 500 (SOAP 1.1, 6.2).
    Soap11,
    /// SOAP 1.2 (ONVIF Core 5.1): `application/soap+xml`, faults with
    /// Code, Subcode and Reason, HTTP 400 for the sender's (SOAP 1.2 part
    /// 2, 7.5.1.2). An envelope that cannot be read is answered so.
    #[default]
    Soap12,
}

impl Version {
    /// The envelope namespace.
    pub fn ns(self) -> &'static str {
        match self {
            Self::Soap11 => NS_SOAP11,
            Self::Soap12 => NS_SOAP,
        }
    }

    /// The HTTP Content-Type of an answer.
    pub fn content_type(self) -> &'static str {
        match self {
            Self::Soap11 => "text/xml; charset=utf-8",
            Self::Soap12 => "application/soap+xml; charset=utf-8",
        }
    }
}

/// A request's envelope: its SOAP version, header and its one operation,
/// the Body's first element (what is asked is that element's namespace
/// and local name, never the HTTP SOAPAction or `action` parameter).
#[derive(Debug)]
pub struct Request {
    pub version: Version,
    pub header: Option<Element>,
    pub operation: Element,
}

/// The envelope's parts, or a fault's reason.
pub fn request(xml: &[u8]) -> Result<Request, String> {
    let root = parse(xml)?;
    let version = match (root.name.as_str(), root.ns.as_str()) {
        ("Envelope", NS_SOAP) => Version::Soap12,
        ("Envelope", NS_SOAP11) => Version::Soap11,
        _ => {
            return Err(format!(
                "expected a SOAP 1.2 ({NS_SOAP}) or SOAP 1.1 ({NS_SOAP11}) Envelope, found {{{}}}{}",
                root.ns, root.name
            ));
        }
    };
    let in_envelope = |name: &str| root.children.iter().find(|c| c.name == name && c.ns == root.ns);
    let header = in_envelope("Header").cloned();
    let body = in_envelope("Body").ok_or("the envelope has no Body")?;
    let operation = body.children.first().cloned().ok_or("the Body is empty")?;
    Ok(Request {
        version,
        header,
        operation,
    })
}

/// Text for XML content and attributes: every character XML 1.0 does not
/// allow at all (control characters but tab, newline and carriage return;
/// U+FFFE, U+FFFF), which no escape can carry, is written as U+FFFD, and
/// the rest goes through quick-xml's escaping (`<`, `>`, `&`, quotes).
pub fn esc(text: &str) -> std::borrow::Cow<'_, str> {
    if text.chars().all(xml_char) {
        escape(text)
    } else {
        let clean: String = text
            .chars()
            .map(|c| if xml_char(c) { c } else { char::REPLACEMENT_CHARACTER })
            .collect();
        std::borrow::Cow::Owned(escape(&clean).into_owned())
    }
}

/// Whether XML 1.0 allows `c` in a document (its `Char` production).
pub fn xml_char(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r' | '\u{20}'..='\u{D7FF}' | '\u{E000}'..='\u{FFFD}' | '\u{10000}'..)
}

const PREFIXES: &str = concat!(
    r#"xmlns:tds="http://www.onvif.org/ver10/device/wsdl" "#,
    r#"xmlns:trt="http://www.onvif.org/ver10/media/wsdl" "#,
    r#"xmlns:tptz="http://www.onvif.org/ver20/ptz/wsdl" "#,
    r#"xmlns:tt="http://www.onvif.org/ver10/schema" "#,
    r#"xmlns:ter="http://www.onvif.org/ver10/error""#
);

/// A response envelope of `version` around `body`.
pub fn envelope(version: Version, body: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?><s:Envelope xmlns:s="{}" {PREFIXES}><s:Body>{body}</s:Body></s:Envelope>"#,
        version.ns()
    )
}

/// A SOAP fault (ONVIF Core 5.11.2): who is at fault, the ONVIF subcodes
/// (`ter:InvalidArgVal`, `ter:NoProfile`, ...) and the reason in words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fault {
    /// `Sender` (the request was wrong) or `Receiver` (the device failed).
    pub sender: bool,
    pub subcodes: Vec<&'static str>,
    pub reason: String,
    /// No valid credentials came: HTTP 401 with a Digest challenge, so
    /// that a client using HTTP Digest authentication knows to answer it.
    pub unauthenticated: bool,
    /// Credentials came and were wrong: the user name they named (the
    /// door logs a failed login with the peer's address).
    pub login_failed: Option<String>,
}

impl Fault {
    pub fn sender(subcodes: &[&'static str], reason: impl Into<String>) -> Self {
        Self {
            sender: true,
            subcodes: subcodes.to_vec(),
            reason: reason.into(),
            unauthenticated: false,
            login_failed: None,
        }
    }

    pub fn receiver(subcodes: &[&'static str], reason: impl Into<String>) -> Self {
        Self {
            sender: false,
            subcodes: subcodes.to_vec(),
            reason: reason.into(),
            unauthenticated: false,
            login_failed: None,
        }
    }

    /// An argument out of range or malformed (`ter:InvalidArgVal`).
    pub fn invalid_arg(detail: &'static str, reason: impl Into<String>) -> Self {
        Self::sender(&["ter:InvalidArgVal", detail], reason)
    }

    /// The HTTP status: 401 without valid credentials; in SOAP 1.2, 400
    /// for the sender's other faults and 500 for the device's; in SOAP 1.1
    /// 500 for every fault (SOAP 1.1, 6.2).
    pub fn status(&self, version: Version) -> u16 {
        match (self.unauthenticated, self.sender, version) {
            (true, _, _) => 401,
            (false, true, Version::Soap12) => 400,
            _ => 500,
        }
    }

    /// The fault envelope in `version`: SOAP 1.2's Code with the ONVIF
    /// subcodes nested (ONVIF Core 5.11.2); SOAP 1.1's `faultcode`
    /// (`s:Client` or `s:Server`, SOAP 1.1, 4.4.1) and `faultstring`, the
    /// ONVIF subcodes in `detail`.
    pub fn envelope(&self, version: Version) -> String {
        if version == Version::Soap11 {
            let detail: String = self
                .subcodes
                .iter()
                .map(|sub| format!("<ter:Subcode>{sub}</ter:Subcode>"))
                .collect();
            return envelope(
                version,
                &format!(
                    "<s:Fault><faultcode>s:{}</faultcode><faultstring>{}</faultstring><detail>{detail}</detail></s:Fault>",
                    if self.sender { "Client" } else { "Server" },
                    esc(&self.reason)
                ),
            );
        }
        let mut code = format!(
            "<s:Value>s:{}</s:Value>",
            if self.sender { "Sender" } else { "Receiver" }
        );
        let mut close = String::new();
        for sub in &self.subcodes {
            code.push_str(&format!("<s:Subcode><s:Value>{sub}</s:Value>"));
            close.push_str("</s:Subcode>");
        }
        envelope(
            version,
            &format!(
                r#"<s:Fault><s:Code>{code}{close}</s:Code><s:Reason><s:Text xml:lang="en">{}</s:Text></s:Reason></s:Fault>"#,
                esc(&self.reason)
            ),
        )
    }
}

#[cfg(test)]
mod tests;
