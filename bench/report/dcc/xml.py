"""Small builders for DCC and D-SI elements, so the writer reads like the certificate.

Numbers are written with `repr(float)`, the shortest text that reads back as the very
same double: a value in the DCC equals the value in result.json bit for bit, and the
certificate's rounding (GUM, 2 significant digits of U) stays a matter of the PDF.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import msgspec
from lxml import etree

from bench.analysis.finite import finite_number as num
from bench.report.dcc import vocab as V

DCC_NS = "https://ptb.de/dcc"
SI_NS = "https://ptb.de/si"
XSI_NS = "http://www.w3.org/2001/XMLSchema-instance"
NSMAP = {"dcc": DCC_NS, "si": SI_NS, "xsi": XSI_NS}
LANG = "en"
COVERAGE_FACTOR = "2"
#: docs/method.md D1: every U is for 95.45 % (k = 2 for infinite nu_eff, t_95.45 otherwise)
COVERAGE_PROBABILITY = "0.9545"
NOT_RECORDED = "not recorded"   # a required field nobody recorded: the gap shows




def dec(x: float) -> str:
    """xs:double text that reads back as exactly `x` (si:decimalType accepts 1e-05)."""
    if float(x).is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(float(x))


def ident(*parts: object) -> str:
    """An xs:ID from parts: letters, digits, '.', '-', '_' only, starting with a letter."""
    text = "_".join(str(p) for p in parts if p is not None and str(p) != "")
    text = re.sub(r"[^A-Za-z0-9._-]", "-", text)
    return text if text[:1].isalpha() else f"x{text}"


def rate_token(rate: float | None) -> str:
    """+10 -> 'p10', -0.1 -> 'm0.1' (for ids)."""
    if rate is None:
        return "na"
    return f"{'m' if rate < 0 else 'p'}{abs(rate):g}"


def el(parent: etree._Element | None, tag: str, text: str | None = None,
       ns: str = DCC_NS, **attrs: str | None) -> etree._Element:
    """A DCC (or, with ns=SI_NS, a D-SI) element; attributes given as None are left out."""
    qname = f"{{{ns}}}{tag}"
    clean = {k.replace("ref_type", "refType").replace("ref_id", "refId"): v
             for k, v in attrs.items() if v is not None}
    node = (etree.SubElement(parent, qname, clean, nsmap=None) if parent is not None
            else etree.Element(qname, clean, nsmap=NSMAP))
    if text is not None:
        node.text = text
    return node


def text_el(parent: etree._Element, tag: str, text: str, **attrs: str | None) -> etree._Element:
    """A dcc:textType / richContentType element with one English content."""
    node = el(parent, tag, None, DCC_NS, **attrs)
    el(node, "content", text or "-", lang=LANG)
    return node


def name(parent: etree._Element, text: str) -> etree._Element:
    return text_el(parent, "name", text)


def expanded_mu(parent: etree._Element, u: float, k: float | None = None) -> None:
    """si:measurementUncertaintyUnivariate/si:expandedMU, p = 95.45 %: k = 2 (normal), or
    the t-factor of the budget's nu_eff (docs/method.md D1; distribution Student t)."""
    mu = el(el(parent, "measurementUncertaintyUnivariate", ns=SI_NS), "expandedMU", ns=SI_NS)
    el(mu, "valueExpandedMU", dec(u), ns=SI_NS)
    t_factor = k is not None and abs(k - 2.0) > 1e-12
    el(mu, "coverageFactor", f"{k:.2f}" if t_factor and k is not None else COVERAGE_FACTOR,
       ns=SI_NS)
    el(mu, "coverageProbability", COVERAGE_PROBABILITY, ns=SI_NS)
    el(mu, "distribution", "t" if t_factor else "normal", ns=SI_NS)


@dataclass(frozen=True)
class Interval:
    """A coverage interval as the certificate prints it (docs/method.md D2): [lower, upper]
    at `probability`; a one-sided limit '< L' is [0 or the floor, L] at its one-sided
    level. `ustd` is the standard uncertainty D-SI asks beside it."""

    lower: float
    upper: float
    probability: float
    ustd: float
    distribution: str


def coverage_interval_mu(parent: etree._Element, iv: Interval) -> None:
    """si:measurementUncertaintyUnivariate/si:coverageIntervalMU (D-SI 2.2: an asymmetric
    interval, not a normal +/- U)."""
    mu = el(el(parent, "measurementUncertaintyUnivariate", ns=SI_NS), "coverageIntervalMU",
            ns=SI_NS)
    el(mu, "valueStandardMU", dec(max(iv.ustd, 0.0)), ns=SI_NS)
    el(mu, "intervalMin", dec(iv.lower), ns=SI_NS)
    el(mu, "intervalMax", dec(iv.upper), ns=SI_NS)
    el(mu, "coverageProbability", dec(iv.probability), ns=SI_NS)
    el(mu, "distribution", iv.distribution, ns=SI_NS)


def si_real(parent: etree._Element, value: float, unit: str, u: float | None = None,
            label: str | None = None, k: float | None = None,
            interval: Interval | None = None) -> etree._Element:
    real = el(parent, "real", ns=SI_NS)
    if label:
        el(real, "label", label, ns=SI_NS)
    el(real, "value", dec(value), ns=SI_NS)
    el(real, "unit", unit, ns=SI_NS)
    if interval is not None:
        coverage_interval_mu(real, interval)
    elif u is not None:
        expanded_mu(real, u, k)
    return real


def si_real_list(parent: etree._Element, values: Sequence[float], unit: str,
                 us: Sequence[float] | None = None) -> etree._Element:
    """si:realListXMLList: values (and their U, k = 2) as whitespace-separated lists."""
    lst = el(parent, "realListXMLList", ns=SI_NS)
    el(lst, "valueXMLList", " ".join(dec(v) for v in values), ns=SI_NS)
    el(lst, "unitXMLList", unit, ns=SI_NS)
    if us is not None:
        mu = el(el(lst, "measurementUncertaintyUnivariateXMLList", ns=SI_NS),
                "expandedMUXMLList", ns=SI_NS)
        el(mu, "valueExpandedMUXMLList", " ".join(dec(u) for u in us), ns=SI_NS)
        el(mu, "coverageFactorXMLList", COVERAGE_FACTOR, ns=SI_NS)
        el(mu, "coverageProbabilityXMLList", COVERAGE_PROBABILITY, ns=SI_NS)
        el(mu, "distributionXMLList", "normal", ns=SI_NS)
    return lst


def quantity(parent: etree._Element, qid: str | None, title: str, ref_type: str,
             value: float, unit: str, u: float | None = None, label: str | None = None,
             note: str | None = None, k: float | None = None,
             interval: Interval | None = None) -> etree._Element:
    """A dcc:quantity with one D-SI real (value, unit, and U with its k, or a coverage
    interval, when given)."""
    q = el(parent, "quantity", id=qid, ref_type=ref_type)
    name(q, title)
    if note:
        text_el(q, "description", note)
    si_real(q, value, unit, u, label, k, interval)
    return q


def list_quantity(parent: etree._Element, qid: str | None, title: str, ref_type: str,
                  values: Iterable[float], unit: str, us: Iterable[float] | None = None,
                  note: str | None = None) -> etree._Element:
    q = el(parent, "quantity", id=qid, ref_type=ref_type)
    name(q, title)
    if note:
        text_el(q, "description", note)
    si_real_list(q, list(values), unit, None if us is None else list(us))
    return q


def statement(parent: etree._Element, ref_type: str | None, declaration: str, *,
              sid: str | None = None, title: str | None = None, norms: Sequence[str] = (),
              references: Sequence[str] = (), conformity: str | None = None
              ) -> etree._Element:
    """A dcc:statement (statementMetaDataType, its children in the schema's order)."""
    st = el(parent, "statement", ref_type=ref_type, id=sid)
    if title:
        name(st, title)
    for norm in norms:
        el(st, "norm", norm)
    for ref in references:
        el(st, "reference", ref)
    text_el(st, "declaration", declaration)
    if conformity:
        el(st, "conformity", conformity)
    return st


def budget_list(data: etree._Element, lid: str, title: str, budget: msgspec.Struct | None,
                path: str, terms: Sequence[tuple[str, str]], unit: str) -> None:
    """The standard uncertainties behind a U, one quantity per source (no U of their own):
    a kind's typed budget's fields named by `terms`."""
    if budget is None:
        return
    found = [(k, label, v) for k, label in terms
             if (v := num(getattr(budget, k, None))) is not None]
    if not found:
        return
    lst = el(data, "list", id=lid, ref_type=V.BUDGET)
    name(lst, title)
    for key, label, v in found:
        quantity(lst, ident(lid, key), f"u({label})", V.STANDARD_UNCERTAINTY, v, unit,
                 label=f"{path}.{key}")
