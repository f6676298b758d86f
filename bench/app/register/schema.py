"""The lab register's tables (SQLAlchemy Core), named `reg_*` so that the register and the
records may share one database. The migrations create them; this module lets the code read
and write them with one definition."""

from __future__ import annotations

import sqlalchemy as sa

metadata = sa.MetaData()

#: ISO/IEC 17025 6.2.5 f, 6.2.6: who may do what is the lab's decision, recorded here

accounts = sa.Table(
    "reg_accounts", metadata,
    sa.Column("name", sa.String(120), primary_key=True),
    sa.Column("full_name", sa.String(200), nullable=False),
    sa.Column("roles", sa.String(200), nullable=False),          # comma-separated, sorted
    sa.Column("function", sa.String(200)),                       # printed under a signature
    sa.Column("password_hash", sa.Text, nullable=False),         # argon2id (argon2-cffi)
    sa.Column("active", sa.Boolean, nullable=False, server_default=sa.true()),
    sa.Column("created_utc", sa.String(40), nullable=False),
    sa.Column("created_by", sa.String(120)),
    # issue 53 (migration g0002): an admin-set password is changed before the account signs
    # or runs; a password older than the register's `password_max_age_days` is refused
    sa.Column("must_change", sa.Boolean, nullable=False, server_default=sa.false()),
    sa.Column("password_changed_utc", sa.String(40)),
)

#: the columns another role may read: everything but the password hash (pgsql.read_grants)
ACCOUNT_PUBLIC = ("name", "full_name", "roles", "function", "active", "created_utc",
                  "created_by", "must_change", "password_changed_utc")

#: failed logins per account name (also for names no account has), and its lock
logins = sa.Table(
    "reg_logins", metadata,
    sa.Column("name", sa.String(120), primary_key=True),
    sa.Column("failures", sa.Integer, nullable=False),
    sa.Column("first_failure_utc", sa.String(40)),
    sa.Column("locked_until_utc", sa.String(40)),
)

equipment = sa.Table(
    "reg_equipment", metadata,
    sa.Column("serial", sa.String(120), primary_key=True),
    sa.Column("model", sa.String(200), nullable=False),
    # the calibration in force now (its history: reg_calibrations); None: identity only
    sa.Column("certificate", sa.String(200)),
    sa.Column("issuer", sa.String(200)),
    sa.Column("due_date", sa.String(10)),                          # YYYY-MM-DD
    sa.Column("added_utc", sa.String(40), nullable=False),
    sa.Column("added_by", sa.String(120), nullable=False),
    # issue 55 (g0003): a drive or fixture, identified but never calibrated (never overdue)
    sa.Column("identity_only", sa.Boolean, nullable=False, server_default=sa.false()),
)

#: every calibration of an item, the earlier ones kept (issue 55; migration g0003): the
#: record in force on a run's date is the latest calibrated on or before it
calibrations = sa.Table(
    "reg_calibrations", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("serial", sa.String(120), sa.ForeignKey("reg_equipment.serial"),
              nullable=False),
    sa.Column("certificate", sa.String(200), nullable=False),
    sa.Column("issuer", sa.String(200), nullable=False),
    sa.Column("calibrated_on", sa.String(10)),    # YYYY-MM-DD; None: not stated (earliest)
    sa.Column("due_date", sa.String(10), nullable=False),          # YYYY-MM-DD
    # as found before adjustment (17025 6.4.13, 7.10): in | out | None (not stated)
    sa.Column("found", sa.String(3)),
    sa.Column("found_error", sa.Float),       # the as-found error, in the item's own unit
    sa.Column("found_error_u", sa.Float),     # its expanded uncertainty
    sa.Column("recorded_utc", sa.String(40), nullable=False),
    sa.Column("recorded_by", sa.String(120), nullable=False),
)

deviations = sa.Table(
    "reg_deviations", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("serial", sa.String(120), sa.ForeignKey("reg_equipment.serial"),
              nullable=False),
    sa.Column("reason", sa.Text, nullable=False),
    sa.Column("expires", sa.String(10), nullable=False),           # YYYY-MM-DD
    sa.Column("recorded_by", sa.String(120), nullable=False),
    sa.Column("recorded_utc", sa.String(40), nullable=False),
    sa.Column("revoked_utc", sa.String(40)),        # g0003: a revoked deviation covers nothing
    sa.Column("revoked_by", sa.String(120)),
)

settings = sa.Table(
    "reg_settings", metadata,
    sa.Column("key", sa.String(80), primary_key=True),
    sa.Column("value", sa.Text, nullable=False),
)

certificates = sa.Table(
    "reg_certificates", metadata,
    sa.Column("number", sa.String(80), primary_key=True),
    sa.Column("seq", sa.Integer, nullable=False, unique=True),
    sa.Column("run_uid", sa.String(64), nullable=False, unique=True),
    sa.Column("allocated_utc", sa.String(40), nullable=False),
)

revisions = sa.Table(
    "reg_revisions", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("number", sa.String(80), sa.ForeignKey("reg_certificates.number"),
              nullable=False),
    sa.Column("revision", sa.Integer, nullable=False),
    sa.Column("issued_utc", sa.String(40), nullable=False),
    sa.Column("signatory", sa.String(120), sa.ForeignKey("reg_accounts.name"),
              nullable=False),
    sa.Column("signatory_name", sa.String(200), nullable=False),
    sa.Column("meaning", sa.String(200), nullable=False),
    sa.Column("reason", sa.Text),
    sa.Column("result_sha256", sa.String(64), nullable=False),
    sa.Column("pdf_sha256", sa.String(64), nullable=False),
    sa.Column("dcc_sha256", sa.String(64), nullable=False),
    sa.Column("html_sha256", sa.String(64), nullable=False),
    sa.Column("withdrawn_utc", sa.String(40)),
    sa.Column("audit_digest", sa.String(64)),
    sa.Column("withdrawn_reason", sa.Text),          # g0003: `bench register withdraw`
    sa.Column("withdrawn_by", sa.String(120)),
    sa.UniqueConstraint("number", "revision", name="reg_revisions_number_revision"),
)

audit = sa.Table(
    "reg_audit", metadata,
    sa.Column("seq", sa.Integer, primary_key=True, autoincrement=False),
    sa.Column("utc", sa.String(40), nullable=False),
    sa.Column("actor", sa.String(120), nullable=False),
    sa.Column("action", sa.String(60), nullable=False),
    sa.Column("object", sa.Text, nullable=False),
    sa.Column("detail", sa.Text, nullable=False),
    sa.Column("db_user", sa.String(120), nullable=False),
    sa.Column("prev_digest", sa.String(64), nullable=False, unique=True),
    sa.Column("digest", sa.String(64), nullable=False),
)

#: the chain's last entry, kept by the register's own append (one row, id = 1)
audit_head = sa.Table(
    "reg_audit_head", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=False),
    sa.Column("seq", sa.Integer, nullable=False),
    sa.Column("digest", sa.String(64), nullable=False),
)

#: each run the register knows, from its start (issue 54): what was measured, by whom, on
#: which items and with which inputs; the result and the raw captures' digests as the
#: bench delivered them at each session's end or analysis (migration g0004)
runs = sa.Table(
    "reg_runs", metadata,
    sa.Column("uid", sa.String(64), primary_key=True),
    sa.Column("bench", sa.String(200), nullable=False),
    sa.Column("performer", sa.String(120)),          # the account authenticated; None: none
    sa.Column("version", sa.String(60), nullable=False),     # ratebench's, at the start
    sa.Column("simulated", sa.Boolean, nullable=False),
    sa.Column("inputs", sa.Text, nullable=False),    # JSON {file: SHA-256} as used
    sa.Column("items", sa.Text, nullable=False),     # JSON: each stand item's status
    sa.Column("registered_utc", sa.String(40), nullable=False),  # the register's clock
    sa.Column("via", sa.String(200), nullable=False),
    sa.Column("result_sha256", sa.String(64)),       # None: no result delivered yet
    sa.Column("result", sa.Text),                    # result.json's bytes (UTF-8)
    sa.Column("result_utc", sa.String(40)),
    sa.Column("raw", sa.Text, nullable=False),       # JSON {raw capture: SHA-256}
)

#: a run's sessions (a resume) and analyses (`bench analyze`), each with the result's
#: digest it delivered and its reason
run_events = sa.Table(
    "reg_run_events", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("uid", sa.String(64), sa.ForeignKey("reg_runs.uid"), nullable=False),
    sa.Column("utc", sa.String(40), nullable=False),
    sa.Column("kind", sa.String(20), nullable=False),  # start|resume|session|analysis
    sa.Column("detail", sa.Text, nullable=False),          # JSON
)
