"""Offline validation of a DCC against the shipped DCC 3.3.0 / D-SI 2.2.1 schemas.

The schemas sit in `bench/app/dcc/schemas/` unmodified (LGPL-3.0, see NOTICE.md there), each at
the path of the URL it is published under. Their `xs:import`s name remote URLs; a resolver
maps each of them to its local file (the same mapping as the shipped catalog.xml), and the
parser is built with `no_network=True`, so libxml2 fetches nothing: validation works on an
air-gapped bench, and an import that was not mapped fails loudly instead of reaching out.
libxml2 validates a demo DCC (1 MB with its PDF) in tens of milliseconds; xmlschema, the
pure-Python validator, takes seconds for the same file, so it serves as the tests' second,
independent opinion. Unit strings, which the XSD types as free text, are checked with
dsiUnits (`bench.report.dcc.units`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

from lxml import etree

from bench.report.dcc.units import unit_list_problems

#: package data read through importlib.resources; libxml2 needs them as real files, which
#: they are in a checkout and in any installed wheel (not inside a zip archive)
SCHEMA_DIR = Path(str(resources.files("bench.app.dcc").joinpath("schemas")))
DCC_XSD = SCHEMA_DIR / "dcc" / "v3.3.0" / "dcc.xsd"
NS = {"dcc": "https://ptb.de/dcc", "si": "https://ptb.de/si",
      "ds": "http://www.w3.org/2000/09/xmldsig#"}
SCHEMA_LOCATION = "https://ptb.de/dcc https://ptb.de/dcc/v3.3.0/dcc.xsd"
#: published URL (with or without www.) -> file under SCHEMA_DIR; the host is cut off
_PUBLISHED = ("dcc/v3.3.0/dcc.xsd", "si/v2.2.1/SI_Format.xsd", "si/v2.2.1/qudt/quantitykind.xsd",
              "dcc/d-sig/xmldsig-core-schema.xsd")
URI_MAP: dict[str, Path] = {f"https://{host}/{rel}": SCHEMA_DIR / rel
                            for host in ("ptb.de", "www.ptb.de") for rel in _PUBLISHED}
MAX_ERRORS = 20


class LocalSchemas(etree.Resolver):
    """libxml2's resolver: the schemas' import URLs -> the shipped files, nothing else."""

    def resolve(self, system_url: str, public_id: str, context: object) -> object:
        local = URI_MAP.get(system_url)
        return self.resolve_filename(str(local), context) if local else None


def _parser() -> etree.XMLParser:
    parser = etree.XMLParser(no_network=True, resolve_entities=False, huge_tree=True)
    parser.resolvers.add(LocalSchemas())
    return parser


@lru_cache(maxsize=1)
def dcc_schema() -> etree.XMLSchema:
    """The DCC 3.3.0 schema with its imports, built once per process, offline."""
    return etree.XMLSchema(etree.parse(str(DCC_XSD), _parser()))


@dataclass(frozen=True)
class Validation:
    """The outcome: schema errors and unit errors, each a readable line."""

    schema_errors: tuple[str, ...]
    unit_errors: tuple[str, ...]

    @property
    def valid(self) -> bool:
        return not self.schema_errors and not self.unit_errors

    def lines(self) -> list[str]:
        return [*self.schema_errors, *self.unit_errors]


def _parse(source: Path | bytes | etree._ElementTree | etree._Element) -> etree._Element:
    if isinstance(source, etree._ElementTree):
        return source.getroot()
    if isinstance(source, etree._Element):
        return source
    parser = etree.XMLParser(no_network=True, resolve_entities=False, huge_tree=True)
    if isinstance(source, bytes):
        return etree.fromstring(source, parser)
    return etree.parse(str(source), parser).getroot()


def validate_dcc(source: Path | bytes | etree._ElementTree | etree._Element) -> Validation:
    """Validate a DCC (file, bytes or lxml tree) offline: XSD, then every D-SI unit string.

    Raises `etree.XMLSyntaxError` for text that is not XML at all.
    """
    root = _parse(source)
    schema = dcc_schema()
    errors: list[str] = []
    if not schema.validate(root):
        for e in schema.error_log:
            errors.append(f"line {e.line}: {e.path}: {e.message}")
            if len(errors) >= MAX_ERRORS:
                errors.append("... (further schema errors not listed)")
                break
    units = [u.text or "" for u in root.iterfind(".//si:unit", NS)]
    units += [u.text or "" for u in root.iterfind(".//si:unitXMLList", NS)]
    return Validation(tuple(errors), tuple(unit_list_problems(units)))


def describe(v: Validation, name: str | Path) -> str:
    if v.valid:
        return f"{name}: valid against DCC 3.3.0 / D-SI 2.2.1 (offline), D-SI units checked"
    return f"{name}: NOT valid ({len(v.lines())} problem(s)):\n" + "\n".join(
        f"  {line}" for line in v.lines())
