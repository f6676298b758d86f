"""The laboratory's settings for the DCC: its contact, persons, and the signing key.

They do not belong to one run, so they live outside the run directory: in a lab settings
file (`--lab FILE`, the environment variable BENCH_LAB_SETTINGS, or the stand file's
`dcc: {lab: FILE}`), and the signing key and certificate may also be named directly in the
stand file (`dcc: {signing: {key: ..., certificate: ...}}`). Only paths are ever written in
those files: a private key's bytes never enter a run directory (the stand file is copied
there), and a key file inside the run directory is refused.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from bench.config import SIGNING, STAND_DCC
from bench.schema import Bool, Check, Key, ListOf, Map, MapOf, Num, Str, validate
from bench.yamlfile import YamlError, load_yaml

__all__ = ["ENV_LAB", "STAND_DCC", "LabSettings", "SettingsError", "load_lab_file",
           "resolve_settings"]

ENV_LAB = "BENCH_LAB_SETTINGS"
PERFORMANCE_LOCATIONS = ("laboratory", "customer", "laboratoryBranch", "customerBranch", "other")


def _country_rule(value: Any) -> str | None:
    if isinstance(value, str) and not (len(value) == 2 and value.isascii() and value.isupper()):
        return f"expected an ISO 3166-1 alpha-2 code such as DE or FR, got {value!r}"
    return None


COUNTRY = Check(Str(), _country_rule)
LOCATION = Map({k: Key(COUNTRY if k == "country_code" else Str())
                for k in ("street", "street_no", "post_code", "city", "state", "country_code",
                          "further")})
CONTACT = Map({
    "name": Key(Str(), True), "email": Key(Str()), "phone": Key(Str()),
    "location": Key(LOCATION),
})
PERSON = Map({"name": Key(Str(), True), "role": Key(Str()), "main_signer": Key(Bool())})
LAB_FILE = Map({
    "laboratory": Key(Map({**CONTACT.keys, "code": Key(Str(), False,
                                                       "accreditation or laboratory code")})),
    "country_code": Key(COUNTRY, False, "country where the calibration is performed"),
    "performance_location": Key(Str(PERFORMANCE_LOCATIONS)),
    "responsible_persons": Key(ListOf(PERSON)),
    "signing": Key(SIGNING),
    # the records' keys (bench/records/settings.py reads them): one lab file for both
    "records": Key(Str(), False, "records database URL"),
    "recertification": Key(Map({
        "default_interval_days": Key(Num(min=1, integer=True, unit="d")),
        "tables": Key(MapOf(Num(min=1, integer=True, unit="d")), False,
                      "serial: recertification interval, days"),
    })),
})


class SettingsError(Exception):
    """A lab settings file or a signing key is unusable; the message names file and key."""


@dataclass(frozen=True)
class Location:
    fields: tuple[tuple[str, str], ...] = ()   # (DCC element, text), in the file's order


@dataclass(frozen=True)
class Contact:
    name: str
    email: str | None = None
    phone: str | None = None
    location: Location = Location()
    code: str | None = None


@dataclass(frozen=True)
class Person:
    name: str
    role: str | None = None
    main_signer: bool = False


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
            raise SettingsError(f"{self.origin}: signing.password_env names "
                                f"{self.password_env}, which is not set")
        return value.encode()


@dataclass(frozen=True)
class LabSettings:
    laboratory: Contact | None = None
    country_code: str | None = None
    performance_location: str | None = None
    persons: tuple[Person, ...] = ()
    signing: Signing | None = None
    source: str = ""


_LOCATION_ELEMENTS = {"street": "street", "street_no": "streetNo", "post_code": "postCode",
                      "city": "city", "state": "state", "country_code": "countryCode",
                      "further": "further"}


def _location(d: Mapping[str, Any] | None) -> Location:
    return Location(tuple((_LOCATION_ELEMENTS[k], str(v)) for k, v in (d or {}).items()
                          if k in _LOCATION_ELEMENTS and str(v).strip()))


def _signing(d: Mapping[str, Any] | None, origin: str) -> Signing | None:
    if not d:
        return None
    return Signing(Path(os.path.expanduser(d["key"])),
                   Path(os.path.expanduser(d["certificate"])), d.get("password_env"), origin)


def load_lab_file(path: str | Path) -> LabSettings:
    """Parse and validate a lab settings file; every problem names file, line and key."""
    try:
        doc = load_yaml(path)
    except YamlError as e:
        raise SettingsError(str(e.problem)) from None
    data = doc.data if doc.data is not None else {}
    problems = validate(doc, LAB_FILE) if isinstance(data, dict) else [
        doc.problem((), "expected a mapping (laboratory: ..., signing: ...)")]
    if problems:
        raise SettingsError("lab settings: " + "; ".join(str(p) for p in problems))
    lab = data.get("laboratory")
    contact = Contact(lab["name"], lab.get("email"), lab.get("phone"),
                      _location(lab.get("location")), lab.get("code")) if lab else None
    return LabSettings(
        laboratory=contact, country_code=data.get("country_code"),
        performance_location=data.get("performance_location"),
        persons=tuple(Person(p["name"], p.get("role"), bool(p.get("main_signer")))
                      for p in data.get("responsible_persons") or []),
        signing=_signing(data.get("signing"), f"{path}: signing"), source=str(path))


def resolve_settings(stand: Mapping[str, Any] | None, lab_file: str | Path | None = None,
                     stand_origin: str = "stand file") -> LabSettings:
    """The lab settings in force: `--lab` first, then the stand's `dcc.lab`, then the
    environment's BENCH_LAB_SETTINGS; the stand's own `dcc.signing` overrides the key."""
    dcc = (stand or {}).get("dcc") or {}
    chosen = lab_file or dcc.get("lab") or os.environ.get(ENV_LAB)
    settings = load_lab_file(os.path.expanduser(str(chosen))) if chosen else LabSettings()
    stand_signing = _signing(dcc.get("signing"), f"{stand_origin}: dcc.signing")
    return settings if stand_signing is None else replace(settings, signing=stand_signing)


def check_key_outside(signing: Signing, run_path: Path) -> None:
    """Refuse a key kept inside the run directory: it would travel with the evidence."""
    key = signing.key_file.resolve()
    if key.is_relative_to(run_path.resolve()):
        raise SettingsError(f"{signing.origin}: the private key {key} lies inside the run "
                            f"directory {run_path}; keep it outside (the run directory is "
                            "handed on with the certificate)")
