"""Every ONVIF response the tests receive, checked against the ONVIF XSDs.

The schemas are those the onvif-zeep-async wheel ships (its `wsdl` folder:
`onvif.xsd` and the message schemas inlined in `devicemgmt.wsdl`,
`media.wsdl` and `ptz.wsdl`), compiled once with lxml's validating parser
(libxml2's XML Schema). `check(body)` validates the element in the SOAP
Body of one raw response (a response of the Device, Media or PTZ service,
or a SOAP fault's ONVIF subcodes) and raises `Invalid` naming the first
invalid element with its path and libxml2's words; `install()` puts that
check in front of zeep, so every response a test's ONVIF client reads is
checked before zeep parses it, and a test fails on the first invalid one.
"""

import os
import tempfile

from lxml import etree

SOAP12 = "http://www.w3.org/2003/05/soap-envelope"
SOAP11 = "http://schemas.xmlsoap.org/soap/envelope/"
ONVIF_NAMESPACES = {
    "http://www.onvif.org/ver10/device/wsdl": "devicemgmt.wsdl",
    "http://www.onvif.org/ver10/media/wsdl": "media.wsdl",
    "http://www.onvif.org/ver20/ptz/wsdl": "ptz.wsdl",
}
XS = "http://www.w3.org/2001/XMLSchema"

_schema = None


class Invalid(AssertionError):
    """A response the ONVIF schemas do not accept."""


def _wsdl_folder():
    import onvif

    return os.path.join(os.path.dirname(onvif.__file__), "wsdl")


def _compile():
    """One schema over the three services' message schemas and onvif.xsd."""
    folder = _wsdl_folder()
    out = tempfile.mkdtemp(prefix="onvif-xsd-")
    imports = []
    for ns, wsdl in ONVIF_NAMESPACES.items():
        tree = etree.parse(os.path.join(folder, wsdl))
        inline = tree.find(f".//{{{XS}}}schema")
        if inline is None or inline.get("targetNamespace") != ns:
            raise Invalid(f"{wsdl}: no inline schema for {ns}")
        for imp in inline.findall(f"{{{XS}}}import"):
            loc = imp.get("schemaLocation")
            if loc:
                imp.set("schemaLocation", "file://" + os.path.join(folder, os.path.basename(loc)))
        path = os.path.join(out, wsdl + ".xsd")
        with open(path, "wb") as f:
            f.write(etree.tostring(inline))
        imports.append(f'<xs:import namespace="{ns}" schemaLocation="file://{path}"/>')
    root = (
        f'<xs:schema xmlns:xs="{XS}" targetNamespace="urn:sagebrush:onvif-tests" '
        'elementFormDefault="qualified">' + "".join(imports) + "</xs:schema>"
    )
    return etree.XMLSchema(etree.fromstring(root.encode(), base_url="file://" + out + "/"))


def schema():
    global _schema
    if _schema is None:
        _schema = _compile()
    return _schema


def _path(element):
    return element.getroottree().getpath(element)


def check(body):
    """Validates one raw response: its Body's element against the ONVIF
    schemas (a fault's ONVIF subcodes must be QNames of the ter namespace).
    Returns the element's local name; raises Invalid on the first error."""
    if isinstance(body, str):
        body = body.encode()
    try:
        doc = etree.fromstring(body)
    except etree.XMLSyntaxError as err:
        raise Invalid(f"not well-formed XML: {err}: {body[:200]!r}") from None
    if etree.QName(doc).localname != "Envelope" or etree.QName(doc).namespace not in (SOAP12, SOAP11):
        raise Invalid(f"not a SOAP envelope: {etree.QName(doc)}")
    soap = etree.QName(doc).namespace
    bodies = doc.findall(f"{{{soap}}}Body")
    if len(bodies) != 1 or len(bodies[0]) != 1:
        raise Invalid("expected one Body with one element")
    element = bodies[0][0]
    name = etree.QName(element)
    if name.namespace == soap and name.localname == "Fault":
        _check_fault(element, soap)
        return "Fault"
    if name.namespace not in ONVIF_NAMESPACES:
        raise Invalid(f"{_path(element)}: {name} is not an ONVIF response element")
    # The element alone, as a document of its own, with the namespaces
    # it uses in scope.
    alone = etree.fromstring(etree.tostring(element))
    validator = schema()
    if not validator.validate(alone):
        first = validator.error_log[0]
        raise Invalid(
            f"{name.localname} is invalid against the ONVIF XSDs at {first.path} (line {first.line}): {first.message}"
        )
    return name.localname


def _check_fault(fault, soap):
    ter = "http://www.onvif.org/ver10/error"
    if soap == SOAP11:
        code = fault.find("faultcode")
        if code is None or fault.find("faultstring") is None:
            raise Invalid(f"{_path(fault)}: a SOAP 1.1 fault needs faultcode and faultstring")
        return
    values = fault.findall(f".//{{{soap}}}Value")
    if not values or fault.find(f"{{{soap}}}Reason/{{{soap}}}Text") is None:
        raise Invalid(f"{_path(fault)}: a SOAP 1.2 fault needs Code/Value and Reason/Text")
    for v in values[1:]:
        prefix, _, _ = v.text.partition(":")
        if v.nsmap.get(prefix) != ter:
            raise Invalid(f"{_path(v)}: subcode {v.text!r} is not a QName of {ter}")


def install():
    """Checks every response onvif-zeep-async's transport receives."""
    from onvif import zeep_aiohttp

    transport = zeep_aiohttp.AIOHTTPTransport
    if getattr(transport.post_xml, "schema_checked", False):
        return
    original = transport.post_xml

    async def post_xml(self, address, envelope, headers):
        response = await original(self, address, envelope, headers)
        check(response.content)
        return response

    post_xml.schema_checked = True
    transport.post_xml = post_xml


if __name__ == "__main__":
    # One raw response on stdin: exit 0 when valid, else 1 with the reason.
    import sys

    try:
        check(sys.stdin.buffer.read())
    except Invalid as err:
        print(err, file=sys.stderr)
        sys.exit(1)
