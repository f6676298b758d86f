"""The DCC's administrativeData: software, refTypes, core data, item, laboratory,
responsible persons, customer and the statements (conformity overall, location, raw-data
digests). What nobody recorded says "not recorded"; nothing is invented.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence

from lxml import etree

import bench
from bench.app.certificate.build import Sources, check_class, decision_rule_text
from bench.app.certificate.equipment import equipment_list, identity_lines
from bench.app.certificate.item import item_record, setting_statements
from bench.app.certificate.item import statements as item_statements
from bench.app.certificate.people import PERFORMED_BY, equipment_lines, performer
from bench.app.certificate.register import Issue
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.events import Event
from bench.core.lab import Lab
from bench.kind import CertificatePart, DccPart
from bench.report.certificate import methods
from bench.report.certificate.parts import stand_of
from bench.report.corrections import statements as correction_statements
from bench.report.dcc import vocab as V
from bench.report.dcc.conformity import ILAC_G8, RULE_REFERENCE
from bench.report.dcc.xml import NOT_RECORDED, el, name, num, statement, text_el
from bench.report.result_frame import CertificateSettings, HashedFile
from bench.report.result_frame import text as text_at

UNKNOWN_COUNTRY = "ZZ"   # ISO 3166-1 user-assigned code: the laboratory did not configure one


def _date(stamp: str | None) -> str | None:
    if not stamp:
        return None
    try:
        t = dt.datetime.fromisoformat(stamp.replace("Z", "+00:00"))
    except ValueError:
        return None
    if t.tzinfo is not None:
        t = t.astimezone(dt.UTC)
    return t.date().isoformat()


def _event(src: Sources, kind: type[Event], last: bool = False) -> str | None:
    return src.event_utc(kind, last)


def administrative(adm: etree._Element, src: Sources, lab: Lab,
                   parts: CertificatePart, kind: DccPart, issue: Issue,
                   today: str) -> None:
    """`parts` answers as on the certificate (its closing statements), `kind` for the DCC
    (the item). `issue` is the PDF's: a draft (no mainSigner, a DRAFT statement and no
    issueDate: the PDF says "none", and DCC 3.3.0 makes the element optional) or the
    issue `bench authorise` records (its authoriser the mainSigner, its date of issue)."""
    cert = src.frame.certificate or src.procedure_file.get("certificate", {}) or {}
    _software(el(adm, "dccSoftware"), src)
    _ref_types(el(adm, "refTypeDefinitions"))
    country = lab.country or text_at(cert, "country_code")
    _core_data(el(adm, "coreData"), src, lab, country, issue, today)
    _item(el(adm, "items"), src, kind)
    _laboratory(el(adm, "calibrationLaboratory"), lab)
    _people(el(adm, "respPersons"), src, issue)
    _customer(el(adm, "customer"), CertificateSettings.of(cert))
    _statements(el(adm, "statements"), src, parts, country, issue, lab)


def _software(soft: etree._Element, src: Sources) -> None:
    """This bench's release, which wrote the DCC, and the one that ran the measurement."""
    versions = dict.fromkeys([bench.__version__, str(src.meta.get("bench_version") or
                                                     bench.__version__)])
    for i, version in enumerate(versions):
        sw = el(soft, "software")
        name(sw, "ratebench (rate-table attestation bench)")
        el(sw, "release", version)
        el(sw, "type", "application")
        text_el(sw, "description", "wrote this DCC" if i == 0 else "ran the measurement")


def _ref_types(defs: etree._Element) -> None:
    """The namespaces of the refTypes used (docs/dcc.md)."""
    for ns in V.NAMESPACES:
        d = el(defs, "refTypeDefinition")
        name(d, ns.name)
        text_el(d, "description", ns.description)
        el(d, "namespace", ns.prefix)
        el(d, "link", ns.link)


def _core_data(core: etree._Element, src: Sources, lab: Lab, country: str | None,
               issue: Issue, today: str) -> None:
    """Country, languages, the certificate's number, the run's identifications, when and
    where the work was done, the date of issue and what a re-issue replaces."""
    el(core, "countryCodeISO3166_1", str(country or UNKNOWN_COUNTRY))
    el(core, "usedLangCodeISO639_1", "en")
    el(core, "mandatoryLangCodeISO639_1", "en")
    el(core, "uniqueIdentifier", issue.number)   # the PDF's number, this issue
    ids = el(core, "identifications")
    run_dir = src.frame.run_dir or (src.run_path.name if src.run_path else None)
    if run_dir:
        idn = el(ids, "identification", ref_type=V.RUN_DIRECTORY)
        el(idn, "issuer", "calibrationLaboratory")
        el(idn, "value", str(run_dir))
        name(idn, "Run directory (raw data and result.json)")
    title = src.frame.title or src.procedure_file.get("title")
    if title:
        idn = el(ids, "identification")
        el(idn, "issuer", "calibrationLaboratory")
        el(idn, "value", str(title))
        name(idn, "Title of the work")
    if not len(ids):
        core.remove(ids)
    dates = src.frame.dates
    begin = (_date(dates.started_utc) or _date(_event(src, ev.SessionStarted))
             or _date(dates.created_utc) or _date(text_at(src.meta, "created_utc")) or today)
    end = (_date(dates.completed_utc) or _date(_event(src, ev.Completed, last=True))
           or begin)
    el(core, "beginPerformanceDate", begin)
    el(core, "endPerformanceDate", end)
    el(core, "performanceLocation", lab.performance_location)
    if not issue.draft:     # a draft has no date of issue (issue 43): nobody issued it
        el(core, "issueDate", issue.issue_date)
    if issue.replaces and not issue.draft:      # a re-issue: say what it replaces
        change = el(core, "reportAmendedSubstituted")
        el(change, "typeOfChange", "substituted")
        el(change, "replacedUniqueIdentifier", issue.replaces)


def _laboratory(labx: etree._Element, lab: Lab) -> None:
    """The laboratory as its settings name it, its address as the PDF prints it."""
    if lab.code:
        el(labx, "calibrationLaboratoryCode", lab.code)
    contact = el(labx, "contact")
    name(contact, str(lab.name or f"laboratory {NOT_RECORDED}"))
    if lab.email:
        el(contact, "eMail", lab.email)
    if lab.phone:
        el(contact, "phone", lab.phone)
    # the address as the PDF prints it, after its parts (where the lab file gives them)
    _location(contact, (*lab.location, *((("further", lab.address),) if lab.address else ())))


def _people(persons: etree._Element, src: Sources, issue: Issue) -> None:
    """As the PDF's authorisation section (bench/app/certificate/people.py): the performer
    the register authenticated (or "not recorded"), then, on an issue, its signatory as
    main signer; a draft names no one who would sign it."""
    performed, how = performer(src.start)
    people = [(performed, f"{PERFORMED_BY} ({how})", False)]
    if not issue.draft:
        people.append((str(issue.signatory), f"{issue.function or 'Authorised signatory'}; "
                       f"{issue.meaning or 'authorised for issue'} ({issue.issued_utc})",
                       True))
    for person_name, role, main in people:
        rp = el(persons, "respPerson")
        name(el(rp, "person"), person_name)
        el(rp, "role", role)
        if main:
            el(rp, "mainSigner", "true")


def _customer(customer: etree._Element, cert: CertificateSettings) -> None:
    """The customer, with the address (or location) and contact the certificate settings
    give."""
    name(customer, str(cert.customer or f"customer {NOT_RECORDED}"))
    where = cert.customer_address or dict(cert.entries).get("customer_location")
    fields = [("further", str(where))] if where else []
    if cert.customer_contact:
        fields.append(("further", f"Contact: {cert.customer_contact}"))
    _location(customer, fields)


def _location(parent: etree._Element, fields: Sequence[tuple[str, str]]) -> None:
    loc = el(parent, "location")
    for tag, value in fields or (("further", f"address {NOT_RECORDED}"),):
        if tag == "further":
            text_el(loc, tag, value)
        else:
            el(loc, tag, value)


def _item(items: etree._Element, src: Sources, kind: DccPart) -> None:
    stand = stand_of(src)
    item = el(items, "item", id="item")
    what, named_axes = kind.dcc_item(src)
    name(item, " ".join(str(x) for x in (stand.maker, stand.model) if x)
         or f"{what} ({NOT_RECORDED})")
    axes = ", ".join(named_axes)
    text = f"Item calibrated: {what}" + (f"; axes {axes}" if axes else "") + "."
    if stand.simulated:
        text += (" SIMULATED stand: instrument twins on real channels; these results "
                 "describe no physical item.")
    if stand.file:
        digest = NOT_RECORDED if stand.sha256 is None else stand.sha256
        text += f" Stand file {stand.file} (SHA-256 {digest})."
    text_el(item, "description", text)
    if stand.maker:
        name(el(item, "manufacturer"), str(stand.maker))
    if stand.model:
        el(item, "model", str(stand.model))
    ids = el(item, "identifications")
    idn = el(ids, "identification")
    el(idn, "issuer", "manufacturer")
    el(idn, "value", str(stand.serial or NOT_RECORDED))
    name(idn, "Serial number")


def _statements(sts: etree._Element, src: Sources, parts: CertificatePart,
                country: str | None, issue: Issue, lab: Lab) -> None:
    """The statements, in the PDF's order: the authorisation (or the draft's), the
    corrections applied, the closing statements the kind's results take, the PDF's
    authority, the overall conformity, what the PDF says of the stand and its equipment,
    and the raw files' digests."""
    _authorisation(sts, issue)
    for text in correction_statements(src.frame.corrections):    # issue 58: as the PDF says it
        statement(sts, None, text, title="Corrections applied")
    first = methods.STATEMENTS[0]
    for text in parts.certificate_statements(methods.STATEMENTS):   # those the PDF prints
        refs = ("7.8.2.1 l)",) if text == first else ("7.8",)
        text = (text.replace("as identified in section 1", "identified under items")
                .replace("printed in % or in ppm (1 ppm = 0.0001 %) as the column header "
                         "states", "given here as plain fractions (unit \\one); the PDF "
                         "prints them in % or ppm"))
        statement(sts, None, text, norms=("ISO/IEC 17025:2017",), references=refs)
    statement(sts, None, "The PDF embedded here (certificate.pdf, under document) is the "
              "authoritative form of this certificate; this XML carries the same results, "
              "unrounded, for machines to read.")
    _conformity(sts, src)
    _stand_statements(sts, src, lab, country)
    _digests(sts, src)


def _authorisation(sts: etree._Element, issue: Issue) -> None:
    """A draft's DRAFT, NOT AUTHORISED; an issue's authoriser, with its electronic
    signature, its receipt and what a re-issue replaces."""
    if issue.draft:
        statement(sts, V.DRAFT, "DRAFT, NOT AUTHORISED: this draft has not been authorised "
                  "for issue and is not a certificate; `bench authorise RUN_DIR --signatory "
                  "NAME` issues it.", sid="draftStatus", title="Draft")
    else:
        text = (f"Authorised for issue on {issue.issue_date} ({issue.issued_utc}) by "
                f"{issue.signatory}" + (f", {issue.function}" if issue.function else "") + ".")
        if issue.register:
            text += (f" Electronic signature: {issue.signatory}, {issue.issued_utc}, meaning "
                     f"'{issue.meaning or 'authorised for issue'}', authenticated by name "
                     f"and password by the lab register {issue.register}.")
        if issue.receipt:
            text += f" {issue.receipt}."
        if issue.replaces:
            text += (f" Revision {issue.revision}: it replaces certificate {issue.replaces}, "
                     "which is withdrawn." + (f" Reason: {issue.reason}." if issue.reason
                                               else "")
                     + (" What changed: " + "; ".join(issue.changes) + "."
                        if issue.changes else ""))
        statement(sts, V.AUTHORISATION, text, sid="authorisation", title="Authorisation")


def _conformity(sts: etree._Element, src: Sources) -> None:
    """The overall statement of conformity under the run's decision rule (ILAC-G8), with
    the checks not assessed and the consistency checks counted apart."""
    verdict = (src.frame.verdict or "incomplete").lower()
    rule = src.frame.decision_rule or "simple"
    overall = {"pass": "pass", "fail": "fail"}.get(verdict)
    classes = [check_class(c) for c in src.frame.checks]
    n, na = classes.count("conformity"), classes.count("not-assessed")
    cons = classes.count("consistency")
    text = (f"Overall statement of conformity: {verdict.upper()} ({n} check(s) of conformity, "
            "each stated with the quantity it judges"
            + (f"; {na} check(s) NOT ASSESSED, left out of the verdict" if na else "")
            + (f"; {cons} consistency check(s), not conformity" if cons else "")
            + "). " + decision_rule_text(rule))
    statement(sts, V.CONFORMITY, text, sid="overallConformity", title="Conformity",
              norms=(ILAC_G8,), references=(RULE_REFERENCE.get(rule, rule),),
              conformity=overall)


def _stand_statements(sts: etree._Element, src: Sources, lab: Lab, country: str | None
                      ) -> None:
    """As the PDF: the item's location, a simulated stand, the equipment and its identity,
    the item as received and as left, settings and their read-back, the accreditation,
    and a country not configured."""
    stand = stand_of(src)
    if stand.location:
        st = statement(sts, V.LOCATION, "Location of the item during the calibration.")
        loc = el(st, "location")
        text_el(loc, "further", str(stand.location))
    if stand.simulated:
        statement(sts, V.SIMULATED, "SIMULATED stand: every instrument was a simulated "
                  "twin on a real channel; the results describe no physical item.")
    for i, line in enumerate(equipment_lines(src.start, bool(stand.simulated))):
        statement(sts, V.EQUIPMENT, line, sid=f"equipment{i + 1}", title="Equipment",
                  norms=("ISO/IEC 17025:2017",), references=("6.4.13",))
    # as the PDF's deviations: items without an identity of their own (issue 43)
    for i, line in enumerate(identity_lines(equipment_list(src), bool(stand.simulated))):
        statement(sts, V.EQUIPMENT_IDENTITY, line, sid=f"equipmentIdentity{i + 1}",
                  title="Equipment identity", norms=("ISO/IEC 17025:2017",),
                  references=("6.4.13 a",))
    # as the PDF: the item as received and as left, the rule's agreement, settings that
    # differ from their read-back (bench/app/certificate/item.py, computed once)
    record = item_record(src)
    for i, line in enumerate(item_statements(record)):
        statement(sts, V.ITEM_STATE, line, sid=f"itemState{i + 1}", title="Item as received "
                  "and as left", norms=("ISO/IEC 17025:2017",),
                  references=("7.8.2.1 g", "7.8.4.1 b", "7.1.3"))
    for i, line in enumerate(setting_statements(record)):
        statement(sts, V.READBACK, line, sid=f"readback{i + 1}", title="Settings and read-back")
    # an accreditation statement only where the laboratory's settings state one
    if lab.accreditation:
        statement(sts, V.ACCREDITATION, f"Accreditation: {lab.accreditation}",
                  title="Accreditation")
    if not country:
        statement(sts, V.COUNTRY_UNKNOWN, "The laboratory configured no country: the "
                  f"country code {UNKNOWN_COUNTRY} (ISO 3166-1 user-assigned) stands for "
                  "'not recorded'.")


def _digests(sts: etree._Element, src: Sources) -> None:
    files = list(src.frame.raw_files)
    if not files and src.run_path is not None and layout.raw_root(src.run_path).is_dir():
        from bench.core.journal import sha256_file

        files = [HashedFile(p.relative_to(src.run_path).as_posix(), sha256_file(p),
                            p.stat().st_size)
                 for p in sorted(layout.raw_root(src.run_path).rglob("*")) if p.is_file()]
    if not files:
        statement(sts, V.RAW_DIGESTS, "No raw data files were recorded.")
        return
    st = statement(sts, V.RAW_DIGESTS, "SHA-256 digests of the raw data as received from "
                   "the instruments (path in the run directory, then the digest in hex); "
                   "`bench analyze RUN_DIR` recomputes every result from these bytes.",
                   title="Raw data files")
    data = el(st, "data")
    for f in files:
        t = el(data, "text", ref_type=V.SHA256)
        name(t, str(f.path or NOT_RECORDED))
        el(t, "content", str(f.sha256 or NOT_RECORDED))
        if num(f.bytes) is not None:
            el(t, "content", f"{int(num(f.bytes) or 0)} bytes")
