"""The options of `bench authorise`, `bench register` and the records commands (`history`,
`records`, `due`, `control`), apart from the code that runs them.

bench/app/cli.py builds the whole parser for every call, `bench --help` included, so what
it imports to do so must be light: this module imports the standard library only (the
packages bench.app.certificate and bench.app.register load the PDF renderer and the
database at import; bench.app.records.settings loads the lab model). A command's module is
imported when the command runs. tests/test_cli_imports.py holds `import bench.app.cli` to
that. The names shared with those modules are in bench/app/names.py; the records commands'
names are checked equal to their handlers' there too.
"""

from __future__ import annotations

import argparse
import datetime as dt

from bench.app.names import DEFAULT_RUNS, ROLES

#: the subcommands add_records_parsers adds (bench.app.records.commands.RECORDS_COMMANDS)
RECORDS_COMMAND_NAMES = ("history", "records", "due", "control")


def add_authorise_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The `authorise` subcommand (bench/app/certificate/authorise.py runs it)."""
    p = sub.add_parser("authorise", help="issue the run's draft certificate under an "
                                         "authorised signatory; exit 2 when refused")
    p.add_argument("run_dir")
    p.add_argument("--signatory", required=True,
                   help="the signatory's account in the lab register (its password is "
                        "asked: name and password are the e-signature)")
    p.add_argument("--password-stdin", action="store_true",
                   help="read the signatory's password from standard input")
    p.add_argument("--reason", help="why a revision is re-issued (required for a re-issue)")
    p.add_argument("--lab", help="lab settings file naming the register (default: the "
                                 "run's own copy)")


def add_records_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The records subcommands (bench/app/records/commands.py runs them)."""
    _add_history_parser(sub)
    _add_records_parser(sub)
    _add_due_parser(sub)
    _add_control_parser(sub)


def _add_history_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench history`: one table's recorded runs."""
    his = sub.add_parser("history", help="every recorded run of one table, with a trend plot")
    his.add_argument("serial", help="the table's serial number (stand.serial)")
    where = his.add_mutually_exclusive_group()
    where.add_argument("--runs", help="runs folder whose records.sqlite to read (runs/)")
    where.add_argument("--records", help="records database URL")
    his.add_argument("--lab", metavar="FILE", help="the lab file (its records:; default "
                                                   "$BENCH_LAB_SETTINGS; two that differ refuse)")
    his.add_argument("--csv", help="write every recorded figure of the table to this CSV")
    his.add_argument("--plot", help="trend plot PNG (default history-SERIAL.png beside the "
                                    "records database, or in the runs folder)")


def _add_records_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench records`: the records database's import, set-up and benches."""
    rec = sub.add_parser("records", help="the records database")
    rsub = rec.add_subparsers(dest="records_command", required=True, metavar="ACTION")
    imp = rsub.add_parser("import", help="register existing run directories (idempotent)")
    imp.add_argument("runs_dir")
    imp.add_argument("--records", help="records database URL (default: the lab file's "
                                       "records:, else RUNS_DIR/records.sqlite)")
    imp.add_argument("--lab", metavar="FILE", help="the lab file (its records:; default "
                                                   "$BENCH_LAB_SETTINGS; two that differ refuse)")
    ini = rsub.add_parser("init", help="create or migrate the lab's records database on "
                                       "PostgreSQL and grant the benches' and station's roles",
                          description="Run as the lab database's owner: creates or migrates "
                          "the schema, then grants --bench-role what a bench's delivery and "
                          "registration need and --station-role read access "
                          "(docs/station.md). Exit 0 done, 1 unreachable, 2 not PostgreSQL.")
    ini.add_argument("url", help="postgresql://OWNER@HOST/DB")
    ini.add_argument("--bench-role", metavar="ROLE", action="append", default=[],
                     help="the benches' database role (repeatable)")
    ini.add_argument("--station-role", metavar="ROLE", action="append", default=[],
                     help="the station's database role (repeatable)")
    bad = rsub.add_parser("bench", help="bind a bench's name to its database role (the "
                          "owner acts): the role then writes only that bench's rows").add_subparsers(
        dest="bench_command", required=True, metavar="ACTION")
    bnd = bad.add_parser("add", help="NAME's rows are written by ROLE alone (row security)")
    bnd.add_argument("name", help="the bench's name (its stand file's bench.name)")
    bnd.add_argument("--role", required=True, help="its PostgreSQL role")
    bnd.add_argument("--records", metavar="URL", required=True,
                     help="the lab database as its owner (postgresql://OWNER@HOST/DB)")
    _add_delivery_parsers(rsub)


def _add_delivery_parsers(rsub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench records sync` and `check`: a bench's runs delivered to the lab database, and
    compared with it."""
    syn = rsub.add_parser("sync", help="deliver this bench's runs (events, results, records) "
                                       "to the lab's PostgreSQL database (idempotent)",
                          description="Deliver every run directory of the runs folder to the "
                          "lab database: the event lines it does not hold yet, the result, "
                          "the run's records. Repeating it adds nothing. Exit 0 delivered, "
                          "1 the lab database is unreachable, 2 not a PostgreSQL URL.")
    syn.add_argument("--records", metavar="URL", help="the lab database (default: the lab "
                                                      "file's records:)")
    syn.add_argument("--runs", default=DEFAULT_RUNS, help="the runs folder (runs/)")
    syn.add_argument("--lab", metavar="FILE", help="the lab file for runs that copied none "
                                                   "(each run is delivered to the records of "
                                                   "the lab file it copied)")
    syn.add_argument("--batch", type=int, default=500, metavar="LINES",
                     help="event lines per transaction (500)")
    chk = rsub.add_parser("check", help="compare what the lab database holds of runs (events, "
                                        "raw digests, result) with their run directories",
                          description="For each RUN: every event line the lab database holds "
                          "against events.jsonl (by line number), the result against "
                          "result.json, and each raw file's SHA-256 the result lists against "
                          "the file. Reads only. Exit 0 equal, 1 a difference (or not yet "
                          "delivered), 2 not a run directory or not a lab server.")
    chk.add_argument("runs", nargs="+", metavar="RUN", help="run directories")
    chk.add_argument("--records", metavar="URL", help="the lab database (default: the run's "
                                                      "lab file's records:)")
    chk.add_argument("--lab", metavar="FILE", help="the lab file for runs that copied none")


def _add_due_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench due`: the tables due for recertification."""
    due = sub.add_parser("due", help="tables due or overdue for recertification")
    due.add_argument("--records", help="records database URL")
    due.add_argument("--runs", default=DEFAULT_RUNS, help="runs folder (records.sqlite)")
    due.add_argument("--lab", metavar="FILE", help="the lab file (its records:; default "
                                                   "$BENCH_LAB_SETTINGS; two that differ refuse)")
    due.add_argument("--within", type=int, default=30, metavar="DAYS",
                     help="also list tables due within DAYS (30)")
    due.add_argument("--all", action="store_true", help="list every table with an interval")
    due.add_argument("--today", type=dt.date.fromisoformat, help=argparse.SUPPRESS)


def _add_control_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench control`: measurement assurance, each instrument's control status."""
    con = sub.add_parser("control", help="measurement assurance: each instrument's control "
                                         "status; with SERIAL its control charts")
    con.add_argument("serial", nargs="?", help="an instrument's serial (bench control lists "
                                               "them)")
    where = con.add_mutually_exclusive_group()
    where.add_argument("--runs", help="runs folder whose records.sqlite to read (runs/)")
    where.add_argument("--records", help="records database URL")
    con.add_argument("--review", metavar="TEXT",
                     help="record a review of SERIAL's status: why it may be used (journaled)")
    con.add_argument("--by", metavar="ACCOUNT",
                     help="with --review: the reviewer's account in the lab register "
                          "(reviewer or quality role), authenticated with its password")
    con.add_argument("--register", metavar="URL",
                     help="the lab register (default: the lab file's register:)")
    con.add_argument("--lab", metavar="FILE", help="the lab file naming the register and "
                                                   "the records (default $BENCH_LAB_SETTINGS)")
    con.add_argument("--password-stdin", action="store_true",
                     help="read the reviewer's password from standard input")
    con.add_argument("--new-baseline", action="store_true",
                     help="with --review: the instrument changed for good (repaired, "
                          "adjusted): its charts restart at the last run, a new baseline")
    con.add_argument("--plot", help="control chart PNG (default control-SERIAL.png beside "
                                    "the records)")


def _date(text: str) -> dt.date:
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected YYYY-MM-DD, got {text!r}") from None


def add_register_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The `register` subcommand (bench/app/register/commands.py runs it)."""
    p = sub.add_parser("register", help="the lab register: accounts, equipment, audit trail",
                       description="The lab register (docs/register.md): who may sign, the "
                       "equipment inventory, certificate numbers and the audit trail. "
                       "Exit 0 done, 1 the audit trail is broken, 2 refused.")
    rs = p.add_subparsers(dest="register_command", required=True, metavar="WHAT")

    _add_register_init_parser(rs)
    _add_user_parsers(rs)
    _add_settings_parsers(rs)
    _add_service_parser(rs)
    _add_equipment_parsers(rs)
    _add_trail_parsers(rs)


def _register_common(c: argparse.ArgumentParser, acting: bool = True) -> None:
    """The options every `bench register` action takes: where the register is, how
    passwords are read, and (acting) the account acting."""
    c.add_argument("--register", metavar="URL", help="the register (default: the lab "
                   "file's register:)")
    c.add_argument("--lab", metavar="FILE", help="lab file naming the register")
    c.add_argument("--password-stdin", action="store_true",
                   help="read the password(s) from standard input, one per line")
    if acting:
        c.add_argument("--as", dest="as_account", required=True, metavar="ACCOUNT",
                       help="the account acting (its password is asked)")


def _add_register_init_parser(rs: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench register init`: the register created or migrated, with its first admin."""
    ini = rs.add_parser("init", help="create or migrate the register with its first admin")
    ini.add_argument("url", help="sqlite:///PATH or postgresql://ROLE@HOST/DB (the owner)")
    ini.add_argument("--admin", required=True, metavar="NAME", help="the first admin account")
    ini.add_argument("--full-name", help="the admin's full name")
    ini.add_argument("--service-role", metavar="ROLE", action="append", default=[],
                     help="PostgreSQL: the register service's database role (bench register "
                     "serve): checks passwords, changes accounts, allocates and issues")
    ini.add_argument("--bench-role", metavar="ROLE", action="append", default=[],
                     help="PostgreSQL: a bench's database role: reads the register (never a "
                     "password hash) and issues nothing itself")
    ini.add_argument("--station-role", metavar="ROLE", action="append", default=[],
                     help="PostgreSQL: the station's database role: reads, like a bench's")
    ini.add_argument("--password-stdin", action="store_true",
                     help="read the admin's new password from standard input")


def _add_user_parsers(rs: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench register user ...`: the accounts."""
    usr = rs.add_parser("user", help="accounts").add_subparsers(
        dest="user_command", required=True, metavar="ACTION")
    ua = usr.add_parser("add", help="add an account (an admin acts)")
    ua.add_argument("name")
    ua.add_argument("--role", action="append", required=True, choices=ROLES)
    ua.add_argument("--full-name", help="printed under a signature (default: NAME)")
    ua.add_argument("--function", help="the person's function in the laboratory")
    _register_common(ua)
    up = usr.add_parser("passwd", help="change a password: your own (--as NAME), or as an "
                        "admin another's (its holder must change it at the next login)")
    up.add_argument("name")
    _register_common(up)
    for verb, what in (("disable", "an account can no longer log in, sign or run"),
                       ("enable", "a disabled account again")):
        uv = usr.add_parser(verb, help=what + " (an admin acts)")
        uv.add_argument("name")
        _register_common(uv)
    ur = usr.add_parser("role", help="grant or revoke a role (an admin acts)")
    ur.add_argument("name")
    g = ur.add_mutually_exclusive_group(required=True)
    g.add_argument("--grant", choices=ROLES, metavar="ROLE")
    g.add_argument("--revoke", choices=ROLES, metavar="ROLE")
    _register_common(ur)
    ul = usr.add_parser("list", help="the accounts, their roles and password state")
    _register_common(ul, acting=False)


def _add_settings_parsers(rs: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench register settings ...`: the register's settings."""
    st = rs.add_parser("settings", help="the register's settings (lockout, password "
                       "age, DCC signing certificate)").add_subparsers(
        dest="settings_command", required=True, metavar="ACTION")
    ss = st.add_parser("set", help="change a setting (an admin acts; audited)")
    ss.add_argument("key")
    ss.add_argument("value")
    _register_common(ss)
    sl = st.add_parser("list", help="the settings in force")
    _register_common(sl, acting=False)


def _add_service_parser(rs: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench register serve`: the register service (bench/app/register/service.py)."""
    sv = rs.add_parser("serve", help="the lab's register service: the one process that "
                       "checks passwords and issues (docs/register.md)")
    sv.add_argument("--db", metavar="URL", help="the register database as the service's "
                    "role (default: $BENCH_REGISTER_DB)")
    sv.add_argument("--host", default="127.0.0.1", help="address to bind (127.0.0.1)")
    sv.add_argument("--port", type=int, default=8741, help="TCP port (8741; 0 picks one)")
    sv.add_argument("--signing-key", metavar="PEM", help="the lab's DCC signing key: held by "
                    "the service alone, used when the register designates its certificate")
    sv.add_argument("--signing-certificate", metavar="PEM", help="its certificate (chain)")
    sv.add_argument("--signing-password-env", metavar="VAR",
                    help="the environment variable holding the key's password")


def _add_equipment_parsers(rs: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench register equipment ...`: the equipment inventory."""
    eq = rs.add_parser("equipment", help="the equipment inventory").add_subparsers(
        dest="equipment_command", required=True, metavar="ACTION")
    ea = eq.add_parser("add", help="record a standard or instrument and its calibration, "
                       "or (--identity-only) an item without one")
    ea.add_argument("serial")
    ea.add_argument("--model", required=True)
    ea.add_argument("--certificate")
    ea.add_argument("--issuer")
    ea.add_argument("--due", type=_date, help="calibration due, YYYY-MM-DD")
    ea.add_argument("--calibrated", type=_date, help="calibrated on, YYYY-MM-DD (today)")
    ea.add_argument("--identity-only", action="store_true",
                    help="a drive or fixture: identified by serial and model, never overdue")
    _register_common(ea)
    eu = eq.add_parser("update", help="record a new calibration of an item (quality or admin); "
                       "the earlier records are kept")
    eu.add_argument("serial")
    for k in ("certificate", "issuer"):
        eu.add_argument(f"--{k}", required=True)
    eu.add_argument("--due", required=True, type=_date, help="calibration due, YYYY-MM-DD")
    eu.add_argument("--calibrated", type=_date, help="calibrated on, YYYY-MM-DD (today)")
    eu.add_argument("--found", choices=("in", "out"),
                    help="as found before adjustment: in or out of tolerance")
    eu.add_argument("--found-error", metavar="V[,U]",
                    help="the as-found error in the item's own unit, and its expanded U")
    _register_common(eu)
    el = eq.add_parser("list", help="the inventory with each item's status today")
    _register_common(el, acting=False)
    eh = eq.add_parser("history", help="one item's calibrations (with as-found) and deviations")
    eh.add_argument("serial")
    _register_common(eh, acting=False)
    ed = eq.add_parser("deviation", help="allow an overdue item until a date, or --revoke "
                       "(quality acts)")
    ed.add_argument("serial")
    ed.add_argument("--reason", help="why, in a sentence")
    ed.add_argument("--expires", type=_date, help="YYYY-MM-DD, at most the register's "
                    "deviation_max_days (30) ahead")
    ed.add_argument("--revoke", action="store_true", help="end the deviation in force")
    _register_common(ed)


def _add_trail_parsers(rs: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench register withdraw` and `audit`: a certificate withdrawn, the trail checked."""
    wd = rs.add_parser("withdraw", help="withdraw an issued certificate (quality or "
                       "signatory), without a replacement")
    wd.add_argument("number")
    wd.add_argument("--reason", required=True, help="why, in a sentence")
    _register_common(wd)
    au = rs.add_parser("audit", help="check the audit trail's chain; exit 1 when broken")
    au.add_argument("--receipts", nargs="+", metavar="DIR",
                    help="also check every receipt in these folders (run directories' "
                    "certificate-register.jsonl, issued HTML and DCC) against the chain: a "
                    "truncated, forked or rewritten trail no longer holds them")
    _register_common(au, acting=False)
