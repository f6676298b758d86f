"""The laboratory's own settings, one model for the certificate, the DCC, the records and
the station: who issues the certificates, where, who may authorise them, the signing key.

A procedure names the lab file with `certificate: {lab: ../lab.yaml}` (relative to the
procedure file); its own `certificate:` keys override the lab file's. They are resolved
once, when the run starts, into result.json's `certificate` block (and the lab file is
copied into the run directory), so a certificate issued later shows who was authorised
when the work was done. The DCC, `bench authorise`, the records and the station read the
same keys through `parse_lab` / `load_lab` into one frozen `Lab`.

Earlier lab files for the DCC wrote `laboratory:` as a mapping (name, code, email, phone,
location) and `responsible_persons:` (name, role, main_signer); both forms are read here.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal

from msgspec import Meta, Struct

from bench.core import rundir_layout as layout
from bench.core.config import SigningFile
from bench.core.schema import struct_at, struct_map, validate
from bench.core.yamlfile import Problem, YamlDoc, YamlError, YamlValue, load_yaml


def _country_rule(value: str) -> str | None:
    if not (len(value) == 2 and value.isascii() and value.isupper()):
        return f"expected an ISO 3166-1 alpha-2 code such as DE or FR, got {value!r}"
    return None


#: a country: its ISO 3166-1 alpha-2 code (the rule `_country_rule`)
Country = Annotated[str, Meta(extra={"check": _country_rule})]
#: a recertification interval, days
Days = Annotated[int, Meta(ge=1, extra={"unit": "d"})]


def _d(description: str) -> Meta:
    return Meta(description=description)


class LocationFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """An address in parts, for the DCC."""

    street: str | None = None
    street_no: str | None = None
    post_code: str | None = None
    city: str | None = None
    state: str | None = None
    country_code: Country | None = None
    further: str | None = None


class ContactFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The laboratory as earlier DCC lab files wrote it: a mapping."""

    name: str
    email: str | None = None
    phone: str | None = None
    location: LocationFile | None = None
    code: Annotated[str, _d("accreditation or laboratory code")] | None = None


class SignatoryFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    name: Annotated[str, _d("the person's name, printed under the signature line")]
    function: Annotated[str, _d("their function in the laboratory")] | None = None
    role: Annotated[str, _d("the same as function (the DCC's word)")] | None = None
    authorises: Annotated[bool, _d("read but not used: the lab register's signatory role "
                                   "decides who may authorise an issue")] | None = None
    main_signer: Annotated[bool, _d("the same as authorises (the DCC's word)")] | None = None


class RecertificationFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    default_interval_days: Days | None = None
    tables: Annotated[dict[str, Days], _d("serial: recertification interval, "
                                          "days")] | None = None


class LabFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The lab settings file's keys, declared once (`bench schema lab`); `parse_lab` reads
    them, and result.json's `certificate` block that carries them, into one `Lab`."""

    laboratory: Annotated[str | ContactFile, _d(
        "the laboratory's name (or name, code, email, phone, location); the certificate "
        "says 'name not given' without it")] | None = None
    address: Annotated[str, _d("the laboratory's address, printed (ISO/IEC 17025 7.8.2.1 "
                               "b)")] | None = None
    location: Annotated[LocationFile, _d("the address in parts, for the DCC")] | None = None
    email: str | None = None
    phone: str | None = None
    code: Annotated[str, _d("accreditation or laboratory code")] | None = None
    accreditation: Annotated[str, _d("accreditation body and number, or 'not "
                                     "accredited'")] | None = None
    site: Annotated[str, _d("where calibrations are performed, when not at the "
                            "address")] | None = None
    prefix: Annotated[str, _d("prefix of generated certificate numbers (default "
                              "RT)")] | None = None
    country_code: Annotated[Country, _d("country where the calibration is "
                                        "performed")] | None = None
    performance_location: Literal["laboratory", "customer", "laboratoryBranch",
                                  "customerBranch", "other"] | None = None
    signatories: Annotated[tuple[SignatoryFile, ...], Meta(
        min_length=1,
        description="named signatories with their functions, for the laboratory's own "
                    "reference only: who may sign and who performed a calibration come from "
                    "the lab register's authenticated accounts (docs/register.md)")] | None \
        = None
    responsible_persons: Annotated[tuple[SignatoryFile, ...], _d(
        "the same as signatories")] | None = None
    authoritative: Annotated[Literal["pdf"], _d("the authoritative form (pdf)")] | None = None
    signing: Annotated[SigningFile, _d("the key the issued DCC is signed with (paths "
                                       "only)")] | None = None
    require_signed_dcc: Annotated[bool, _d("bench verify fails an unsigned DCC (default: "
                                           "true when signing is configured)")] | None = None
    records: Annotated[str, _d("records database URL")] | None = None
    register: Annotated[str, _d(
        "the lab register's URL (sqlite:///PATH or postgresql://...): accounts, equipment, "
        "certificate numbers, audit trail; bench authorise issues only through it "
        "(docs/register.md)")] | None = None
    recertification: RecertificationFile | None = None


LAB = struct_map(LabFile)

RUN_COPY = layout.LAB  # the lab file as used, copied into the run directory
DEFAULT_PREFIX = "RT"


class LabError(ValueError):
    """A lab settings file or a signing key is unusable; the message names file and key."""


@dataclass(frozen=True)
class Signatory:
    name: str
    function: str = ""
    authorises: bool = False


@dataclass(frozen=True)
class Signing:
    key_file: Path
    certificate_file: Path
    password_env: str | None = None
    origin: str = ""          # where it was configured, for messages

    def password(self) -> bytes | None:
        if not self.password_env:
            return None
        value = os.environ.get(self.password_env)
        if value is None:
            raise LabError(f"{self.origin}: signing.password_env names "
                           f"{self.password_env}, which is not set")
        return value.encode()


_LOCATION_ELEMENTS = {"street": "street", "street_no": "streetNo", "post_code": "postCode",
                      "city": "city", "state": "state", "country_code": "countryCode",
                      "further": "further"}


@dataclass(frozen=True)
class Lab:
    """The laboratory as its settings file states it; every default is here, once."""

    name: str | None = None
    address: str | None = None
    location: tuple[tuple[str, str], ...] = ()   # (DCC element, text), in the file's order
    email: str | None = None
    phone: str | None = None
    code: str | None = None
    accreditation: str | None = None
    site: str | None = None
    prefix: str = DEFAULT_PREFIX
    country_code: str | None = None
    performance_location: str = "laboratory"
    signatories: tuple[Signatory, ...] = ()
    signing: Signing | None = None
    require_signed_dcc: bool = False
    records_url: str | None = None
    register_url: str | None = None
    default_interval_days: int | None = None
    interval_days: Mapping[str, int] = field(default_factory=dict)
    source: str = ""

    @property
    def laboratory(self) -> Lab | None:
        """The contact part (the DCC's calibrationLaboratory); None when nothing is named."""
        return self if self.name else None

    @property
    def country(self) -> str | None:
        return self.country_code or dict(self.location).get("countryCode")

    def authoriser(self, name: str) -> Signatory | None:
        """The signatory of that name who may authorise an issue (case-insensitive)."""
        want = " ".join(name.split()).casefold()
        return next((s for s in self.signatories
                     if s.authorises and " ".join(s.name.split()).casefold() == want), None)

    def authorisers(self) -> tuple[Signatory, ...]:
        return tuple(s for s in self.signatories if s.authorises)

    def interval_for(self, serial: str, stand_days: int | None) -> int | None:
        """A table's recertification interval: the lab's per-serial setting, else the
        stand file's, else the lab's default."""
        return self.interval_days.get(serial) or stand_days or self.default_interval_days


def _signatory(p: SignatoryFile) -> Signatory:
    return Signatory(p.name, p.function or p.role or "", bool(p.authorises or p.main_signer))


def _signing(d: SigningFile | None, origin: str) -> Signing | None:
    if d is None or not d.key or not d.certificate:
        return None
    return Signing(Path(os.path.expanduser(d.key)), Path(os.path.expanduser(d.certificate)),
                   d.password_env, origin)


def _location(d: LocationFile | None) -> tuple[tuple[str, str], ...]:
    if d is None:
        return ()
    return tuple((element, str(v)) for k, element in _LOCATION_ELEMENTS.items()
                 if (v := getattr(d, k)) is not None and str(v).strip())


def parse_lab(data: LabFile, source: str = "") -> Lab:
    """One Lab from validated lab keys (a lab file, or result.json's `certificate` block,
    whose other keys, the customer's, are not the lab's and are left alone)."""
    given = data.laboratory
    contact = given if isinstance(given, ContactFile) else ContactFile(name=given or "")
    people = data.signatories or data.responsible_persons or ()
    rec = data.recertification or RecertificationFile()
    signing = _signing(data.signing, f"{source or 'lab settings'}: signing")
    require = data.require_signed_dcc
    return Lab(
        name=contact.name or None, address=data.address or None,
        location=_location(data.location or contact.location),
        email=data.email or contact.email or None,
        phone=data.phone or contact.phone or None,
        code=data.code or contact.code or None,
        accreditation=data.accreditation, site=data.site,
        prefix=data.prefix or DEFAULT_PREFIX,
        country_code=data.country_code,
        performance_location=data.performance_location or "laboratory",
        signatories=tuple(_signatory(p) for p in people),
        signing=signing,
        require_signed_dcc=bool(signing is not None if require is None else require),
        records_url=data.records,
        register_url=_register_url(data.register, source),
        default_interval_days=rec.default_interval_days,
        interval_days=dict(rec.tables or {}), source=source)


def _register_url(url: str | None, source: str) -> str | None:
    """A relative SQLite path is relative to the lab file, as every path in it is."""
    if not url:
        return None
    prefix = "sqlite:///"
    if url.startswith(prefix) and not url[len(prefix):].startswith("/") and source \
            and Path(source).is_file():
        return prefix + str(Path(source).resolve().parent / url[len(prefix):])
    return url


def load_lab(path: str | Path) -> Lab:
    """Parse and validate a lab settings file; every problem names file, line and key."""
    try:
        doc = load_yaml(path)
    except YamlError as e:
        raise LabError(str(e.problem)) from None
    data = doc.data if doc.data is not None else {}
    problems = validate(doc, LAB) if isinstance(data, dict) else [
        doc.problem((), "expected a mapping (laboratory: ..., signatories: ...)")]
    if problems:
        raise LabError("lab settings: " + "; ".join(str(p) for p in problems))
    return parse_lab(struct_at(LabFile, data, ()), str(path))


def lab_path(procedure_path: Path, certificate: YamlValue) -> Path | None:
    """The lab file a procedure names; in a run directory, the copy made when it started
    (whichever file it came from: `--lab`, the procedure's, $BENCH_LAB_SETTINGS)."""
    here = procedure_path.parent
    if (here / layout.META).is_file():  # a run directory: its copy, if one was made
        return here / RUN_COPY if (here / RUN_COPY).is_file() else None
    ref = certificate.get("lab") if isinstance(certificate, dict) else None
    if not isinstance(ref, str):
        return None
    p = Path(ref)
    return p if p.is_absolute() else Path(os.path.normpath(procedure_path.parent / p))


def lab_problems(procedure_path: Path, procedure_doc: YamlDoc,
                 certificate: YamlValue) -> list[Problem]:
    """The lab file named by `certificate.lab`: it exists and its keys are known."""
    path = lab_path(procedure_path, certificate)
    if path is None:
        if isinstance(certificate, dict) and not isinstance(certificate.get("lab", ""), str):
            return [procedure_doc.problem(("certificate", "lab"),
                                          "expected the path of a lab settings file")]
        return []
    try:
        doc = load_yaml(path)
    except YamlError as e:
        if e.problem.key == "(file)":
            return [procedure_doc.problem(("certificate", "lab"),
                                          f"lab settings file {path}: {e.problem.message}")]
        return [e.problem]
    return validate(doc, LAB)


def certificate_settings(procedure_path: Path,
                         certificate: Mapping[str, YamlValue]) -> dict[str, YamlValue]:
    """The lab file's keys under the procedure's own `certificate:` keys, in the files'
    order (result.json's `certificate` block)."""
    own = dict(certificate)
    path = lab_path(procedure_path, own)
    if path is None:
        return own
    lab = load_yaml(path).data
    merged = {**(lab if isinstance(lab, dict) else {}), **own}
    merged["lab"] = path.name
    return merged


class LabKeys(LabFile, frozen=True, kw_only=True, forbid_unknown_fields=False):
    """The lab file's keys as result.json's `certificate` block carries them, beside the
    customer's (bench/core/settings_codec.py decodes it). Typed as the file's, its
    choices as text: the run wrote what it resolved, and the DCC's own schema judges a
    performance location it does not list (`bench dcc` exits 3 and names it)."""

    # a result's text where the file has a choice (Lab keeps text): wider, on purpose
    performance_location: str | None = None  # type: ignore[assignment]
    signatories: tuple[SignatoryFile, ...] | None = None
    responsible_persons: tuple[SignatoryFile, ...] | None = None
    authoritative: str | None = None  # type: ignore[assignment]


def run_lab(run_path: Path, certificate: LabKeys | None) -> Lab:
    """The lab as the run resolved it: result.json's `certificate` block (the lab file's
    keys under the procedure's own), else the lab file copied into the run directory."""
    if certificate is not None and certificate.laboratory:
        return parse_lab(certificate, f"{run_path / layout.RESULT}: certificate")
    copy = Path(run_path) / RUN_COPY
    return load_lab(copy) if copy.is_file() else Lab()
