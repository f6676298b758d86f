"""Enveloped XAdES signature (XAdES-BES / baseline B) of a DCC, and its check.

The DCC schema allows `ds:Signature` as the root's last child; signxml's XAdESSigner puts
it there, with the signing certificate (SigningCertificateV2), the signing time and the
data object format in the signed properties, so whoever holds the file can tell who
signed it, when, and that not one byte of the signed content changed since.

The key stays where the laboratory keeps it (bench.app.dcc.settings): it is read for the
moment of signing and never written anywhere.
"""

from __future__ import annotations

import base64
import datetime as dt
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ec, rsa
from lxml import etree
from signxml import DigestAlgorithm, SignatureMethod
from signxml.xades import XAdESDataObjectFormat, XAdESSigner, XAdESVerifier

from bench.app.dcc.settings import SettingsError, Signing
from bench.app.dcc.validate import NS

#: a DCC's signature covers the document (URI ""), the signed properties and the key info
EXPECT_REFERENCES = 3


def _read(path: Path, what: str, origin: str) -> bytes:
    try:
        return path.read_bytes()
    except OSError as e:
        raise SettingsError(f"{origin}: cannot read the {what} {path}: {e.strerror}") from None


def load_signing_material(signing: Signing) -> tuple[bytes, list[x509.Certificate]]:
    """The private key (PEM) and certificate chain, checked to belong together and to be
    valid today; every refusal names the file and the setting."""
    key_pem = _read(signing.key_file, "private key", signing.origin)
    cert_pem = _read(signing.certificate_file, "certificate", signing.origin)
    try:
        key = serialization.load_pem_private_key(key_pem, signing.password())
    except (ValueError, TypeError) as e:
        raise SettingsError(f"{signing.origin}: key {signing.key_file}: {e}") from None
    try:
        chain = x509.load_pem_x509_certificates(cert_pem)
    except ValueError as e:
        raise SettingsError(f"{signing.origin}: certificate {signing.certificate_file}: "
                            f"{e}") from None
    leaf = chain[0]
    if leaf.public_key().public_bytes(serialization.Encoding.DER,
                                      serialization.PublicFormat.SubjectPublicKeyInfo) != \
            key.public_key().public_bytes(serialization.Encoding.DER,
                                          serialization.PublicFormat.SubjectPublicKeyInfo):
        raise SettingsError(f"{signing.origin}: the certificate {signing.certificate_file} is "
                            f"not the certificate of the key {signing.key_file}")
    now = dt.datetime.now(dt.UTC)
    if not leaf.not_valid_before_utc <= now <= leaf.not_valid_after_utc:
        raise SettingsError(f"{signing.origin}: the certificate {signing.certificate_file} is "
                            f"valid {leaf.not_valid_before_utc:%Y-%m-%d} to "
                            f"{leaf.not_valid_after_utc:%Y-%m-%d}, not today")
    unencrypted = key.private_bytes(serialization.Encoding.PEM,
                                    serialization.PrivateFormat.PKCS8,
                                    serialization.NoEncryption())
    return unencrypted, chain


def _algorithm(key_pem: bytes) -> SignatureMethod:
    key = serialization.load_pem_private_key(key_pem, None)
    if isinstance(key, ec.EllipticCurvePrivateKey):
        return SignatureMethod.ECDSA_SHA256
    if isinstance(key, rsa.RSAPrivateKey):
        return SignatureMethod.RSA_SHA256
    raise SettingsError(f"unsupported key type {type(key).__name__}: use an RSA or EC key")


def sign_tree(tree: etree._ElementTree, signing: Signing) -> etree._ElementTree:
    """The DCC with an enveloped XAdES-BES signature appended as the root's last child."""
    key_pem, chain = load_signing_material(signing)
    signer = XAdESSigner(
        data_object_format=XAdESDataObjectFormat(
            Description="PTB Digital Calibration Certificate (DCC 3.3.0)", MimeType="text/xml"),
        signature_algorithm=_algorithm(key_pem), digest_algorithm=DigestAlgorithm.SHA256)
    certs = [c.public_bytes(serialization.Encoding.PEM).decode("ascii") for c in chain]
    signed = signer.sign(tree.getroot(), key=key_pem, cert=certs)
    return etree.ElementTree(signed)


@dataclass(frozen=True)
class SignatureCheck:
    """A verified signature: the signed content (what the values are read from), signer."""

    signed_root: etree._Element
    subject: str
    trust: str          # how the signer's certificate was checked


def embedded_certificate(data: bytes) -> x509.Certificate | None:
    root = etree.fromstring(data, etree.XMLParser(no_network=True, huge_tree=True))
    node = root.find(".//ds:Signature/ds:KeyInfo/ds:X509Data/ds:X509Certificate", NS)
    if node is None or not (node.text or "").strip():
        return None
    return x509.load_der_x509_certificate(base64.b64decode("".join(node.text.split())))


def verify_signature(data: bytes, trusted_cert: bytes | None = None,
                     ca_file: Path | None = None) -> SignatureCheck:
    """Check the XAdES signature. Raises signxml's InvalidSignature (and kin) when the
    signed content, the signed properties or the key info were changed.

    Trust: a trusted certificate given (the lab's own) must be the signer's; a CA file
    validates the signer's chain; with neither, the certificate embedded in the file is
    used, which proves integrity but not who signed (the result says so).
    """
    verifier = XAdESVerifier()
    embedded = embedded_certificate(data)
    signer: x509.Certificate | None
    if trusted_cert is not None:
        results = verifier.verify(data, x509_cert=trusted_cert.decode("ascii"),
                                  expect_references=EXPECT_REFERENCES)
        signer = x509.load_pem_x509_certificate(trusted_cert)
        trust = "the signer is the trusted certificate given"
    elif ca_file is not None:
        results = verifier.verify(data, ca_pem_file=str(ca_file),
                                  expect_references=EXPECT_REFERENCES)
        signer, trust = embedded, f"the signer's chain validates against {ca_file}"
    else:
        if embedded is None:
            raise ValueError("the signature carries no X.509 certificate")
        results = verifier.verify(
            data, x509_cert=embedded.public_bytes(serialization.Encoding.PEM).decode("ascii"),
            expect_references=EXPECT_REFERENCES)
        signer = embedded
        trust = ("integrity only: checked with the certificate embedded in the file; who "
                 "signed is NOT established (give --cert or --ca)")
    document = next(r for r in results if r.signed_xml is not None and r.signed_xml.tag ==
                    f"{{{NS['dcc']}}}digitalCalibrationCertificate")
    subject = signer.subject.rfc4514_string() if signer is not None else "unknown"
    return SignatureCheck(document.signed_xml, subject, trust)
