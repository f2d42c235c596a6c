use super::*;

#[test]
fn a_request_is_read_with_its_namespaces() {
    let xml = br#"<?xml version="1.0"?><e:Envelope xmlns:e="http://www.w3.org/2003/05/soap-envelope"><e:Header><Security xmlns="x"><UsernameToken><Username>ad&amp;min</Username></UsernameToken></Security></e:Header><e:Body><GetStatus xmlns="http://www.onvif.org/ver20/ptz/wsdl"><ProfileToken>p1</ProfileToken></GetStatus></e:Body></e:Envelope>"#;
    let r = request(xml).unwrap();
    assert_eq!(r.operation.name, "GetStatus");
    assert_eq!(r.operation.ns, NS_PTZ);
    assert_eq!(r.operation.text_at(&["ProfileToken"]), Some("p1"));
    let h = r.header.unwrap();
    assert_eq!(h.text_at(&["Security", "UsernameToken", "Username"]), Some("ad&min"));
}

#[test]
fn malformed_documents_are_errors_never_panics() {
    for bad in [
        &b"<a><b></a>"[..],
        b"<a>",
        b"",
        b"\xff\xfe",
        b"<a/><b/>",
        b"<x:a/>",
        b"<!DOCTYPE a [<!ENTITY e 'x'>]><a>&e;</a>",
        b"<Envelope xmlns=\"http://www.w3.org/2003/05/soap-envelope\"><Body/></Envelope>",
    ] {
        assert!(request(bad).is_err(), "{:?}", String::from_utf8_lossy(bad));
    }
    let deep = "<a>".repeat(100) + &"</a>".repeat(100);
    assert!(parse(deep.as_bytes()).is_err());
}

#[test]
fn a_fault_carries_its_subcodes_and_escaped_reason() {
    let f = Fault::invalid_arg("ter:NoProfile", "no profile <x>").envelope(Version::Soap12);
    assert!(f.contains("<s:Value>s:Sender</s:Value><s:Subcode><s:Value>ter:InvalidArgVal</s:Value><s:Subcode><s:Value>ter:NoProfile</s:Value></s:Subcode></s:Subcode>"), "{f}");
    assert!(f.contains("no profile &lt;x&gt;"));
    parse(f.as_bytes()).unwrap();
}

#[test]
fn text_that_xml_cannot_carry_is_replaced_and_markup_escaped() {
    assert_eq!(esc("gate \u{1}<b>&\"2\""), "gate \u{FFFD}&lt;b&gt;&amp;&quot;2&quot;");
    assert_eq!(esc("tab\tok\u{FFFE}"), "tab\tok\u{FFFD}");
    let doc = envelope(
        Version::Soap12,
        &format!("<tt:Name>{}</tt:Name>", esc("a\u{0}\u{1b}[31m<x>")),
    );
    parse(doc.as_bytes()).unwrap();
    assert!(!doc.contains('\u{0}') && !doc.contains('\u{1b}'));
}

#[test]
fn a_soap_1_1_request_is_read_and_answered_in_soap_1_1() {
    let xml = br#"<soapenv:Envelope xmlns:soapenv="http://schemas.xmlsoap.org/soap/envelope/"><soapenv:Body><GetNodes xmlns="http://www.onvif.org/ver20/ptz/wsdl"/></soapenv:Body></soapenv:Envelope>"#;
    let r = request(xml).unwrap();
    assert_eq!(r.version, Version::Soap11);
    assert_eq!(
        (r.operation.ns.as_str(), r.operation.name.as_str()),
        (NS_PTZ, "GetNodes")
    );
    assert_eq!(Version::Soap11.content_type(), "text/xml; charset=utf-8");
    let doc = parse(envelope(Version::Soap11, "<tptz:GetNodesResponse/>").as_bytes()).unwrap();
    assert_eq!((doc.ns.as_str(), doc.name.as_str()), (NS_SOAP11, "Envelope"));
    let f = Fault::invalid_arg("ter:NoProfile", "no <profile>");
    let doc = parse(f.envelope(Version::Soap11).as_bytes()).unwrap();
    let fault = doc.path(&["Body", "Fault"]).unwrap();
    assert_eq!(fault.text_at(&["faultcode"]), Some("s:Client"));
    assert_eq!(fault.text_at(&["faultstring"]), Some("no <profile>"));
    let subcodes: Vec<_> = fault
        .child("detail")
        .unwrap()
        .children
        .iter()
        .map(|c| c.text.as_str())
        .collect();
    assert_eq!(subcodes, ["ter:InvalidArgVal", "ter:NoProfile"]);
    // SOAP 1.1 answers every fault with 500; SOAP 1.2 the sender's with 400.
    assert_eq!((f.status(Version::Soap11), f.status(Version::Soap12)), (500, 400));
    // A Header or Body of another namespace is not the envelope's.
    let foreign = br#"<e:Envelope xmlns:e="http://schemas.xmlsoap.org/soap/envelope/"><Body xmlns="urn:x"><GetNodes/></Body></e:Envelope>"#;
    assert!(request(foreign).is_err());
}
