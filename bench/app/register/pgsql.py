"""What PostgreSQL itself enforces for the register (docs/register.md, trust model).

The bench's database role reads the register and calls these functions; it has no
INSERT, UPDATE or DELETE on accounts, equipment, certificate numbers, revisions or the
audit trail (`grant_bench_role`). The functions run as the register's owner (SECURITY
DEFINER), take one lock (so two benches issuing at once are serialised and never get one
number or one revision twice, with the unique constraints as the backstop), check what
the database can check (the signatory's account is active and holds the role, the
revision follows the last one, a re-issue has a reason), and write the audit entry in the
same transaction. The SQLite path does the same in Python (bench/app/register/store.py).
"""

from __future__ import annotations

LOCK_KEY = 7240001      # pg_advisory_xact_lock key: one writer of the register at a time

APPEND = r"""
CREATE OR REPLACE FUNCTION reg_audit_append(p_actor text, p_action text, p_object text,
                                            p_detail text) RETURNS text
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public AS $$
DECLARE prev text; n bigint; t text; d text; u text := session_user::text;
BEGIN
  PERFORM pg_advisory_xact_lock(LOCK_KEY_VALUE);
  SELECT seq, digest INTO n, prev FROM reg_audit_head WHERE id = 1;
  n := coalesce(n, 0) + 1;
  prev := coalesce(prev, repeat('0', 64));
  t := to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS.US"Z"');
  -- bench/app/register/chain.py entry_digest: the same text, hashed the same way
  d := encode(sha256(convert_to(concat_ws(E'\n', prev, n::text, t, p_actor, p_action,
                                          p_object, p_detail, u), 'UTF8')), 'hex');
  INSERT INTO reg_audit(seq, utc, actor, action, object, detail, db_user, prev_digest, digest)
       VALUES (n, t, p_actor, p_action, p_object, p_detail, u, prev, d);
  INSERT INTO reg_audit_head(id, seq, digest) VALUES (1, n, d)
       ON CONFLICT (id) DO UPDATE SET seq = EXCLUDED.seq, digest = EXCLUDED.digest;
  RETURN d;
END $$;
""".replace("LOCK_KEY_VALUE", str(LOCK_KEY))

ALLOCATE = r"""
CREATE OR REPLACE FUNCTION reg_allocate(p_run_uid text, p_prefix text, p_actor text)
RETURNS text
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public AS $$
DECLARE num text; s int; t text;
BEGIN
  PERFORM pg_advisory_xact_lock(LOCK_KEY_VALUE);
  SELECT number INTO num FROM reg_certificates WHERE run_uid = p_run_uid;
  IF num IS NOT NULL THEN RETURN num; END IF;
  SELECT coalesce(max(seq), 0) + 1 INTO s FROM reg_certificates;
  t := to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS"Z"');
  num := p_prefix || '-' || substr(t, 1, 4) || '-' || lpad(s::text, 5, '0');
  INSERT INTO reg_certificates(number, seq, run_uid, allocated_utc) VALUES (num, s, p_run_uid, t);
  PERFORM reg_audit_append(p_actor, 'number allocated', num, 'run ' || p_run_uid);
  RETURN num;
END $$;
""".replace("LOCK_KEY_VALUE", str(LOCK_KEY))

ISSUE = r"""
CREATE OR REPLACE FUNCTION reg_issue(p_number text, p_revision int, p_signatory text,
    p_meaning text, p_reason text, p_issued_utc text, p_result text, p_pdf text,
    p_dcc text, p_html text, p_detail text) RETURNS text
LANGUAGE plpgsql SECURITY DEFINER SET search_path = public AS $$
DECLARE last int; acct record; d text;
BEGIN
  PERFORM pg_advisory_xact_lock(LOCK_KEY_VALUE);
  SELECT * INTO acct FROM reg_accounts WHERE name = p_signatory;
  IF acct IS NULL OR NOT acct.active
     OR NOT (',' || acct.roles || ',') LIKE '%,signatory,%' THEN
    RAISE EXCEPTION 'register: % is not an active signatory account', p_signatory;
  END IF;
  IF NOT EXISTS (SELECT 1 FROM reg_certificates WHERE number = p_number) THEN
    RAISE EXCEPTION 'register: certificate number % was not allocated by this register',
                    p_number;
  END IF;
  SELECT coalesce(max(revision), 0) INTO last FROM reg_revisions WHERE number = p_number;
  IF p_revision <> last + 1 THEN
    RAISE EXCEPTION 'register: % revision % is not the next (revision % is the last issued)',
                    p_number, p_revision, last;
  END IF;
  IF last > 0 AND coalesce(btrim(p_reason), '') = '' THEN
    RAISE EXCEPTION 'register: a re-issue of % needs a reason', p_number;
  END IF;
  UPDATE reg_revisions SET withdrawn_utc = p_issued_utc
   WHERE number = p_number AND withdrawn_utc IS NULL;
  d := reg_audit_append(p_signatory, CASE WHEN last = 0 THEN 'issue' ELSE 're-issue' END,
                        p_number || ' revision ' || p_revision, p_detail);
  INSERT INTO reg_revisions(number, revision, issued_utc, signatory, signatory_name, meaning,
                            reason, result_sha256, pdf_sha256, dcc_sha256, html_sha256,
                            audit_digest)
       VALUES (p_number, p_revision, p_issued_utc, p_signatory, acct.full_name, p_meaning,
               nullif(btrim(p_reason), ''), p_result, p_pdf, p_dcc, p_html, d);
  RETURN d;
END $$;
""".replace("LOCK_KEY_VALUE", str(LOCK_KEY))

FUNCTIONS = (APPEND, ALLOCATE, ISSUE)

#: what every role may not do to the functions: run them unless granted
REVOKE_PUBLIC = [
    "REVOKE ALL ON FUNCTION reg_audit_append(text, text, text, text) FROM PUBLIC",
    "REVOKE ALL ON FUNCTION reg_allocate(text, text, text) FROM PUBLIC",
    "REVOKE ALL ON FUNCTION reg_issue(text, int, text, text, text, text, text, text, text, "
    "text, text) FROM PUBLIC",
]


FUNCTION_SIGNATURES = (
    "reg_audit_append(text, text, text, text)",
    "reg_allocate(text, text, text)",
    "reg_issue(text, int, text, text, text, text, text, text, text, text, text)",
)

#: tables the register service writes (issue 53): accounts and their logins, equipment,
#: deviations, settings; numbers, revisions and the trail only through the functions
SERVICE_WRITES = ("reg_accounts", "reg_logins", "reg_equipment", "reg_deviations",
                  "reg_settings", "reg_calibrations")
READ_TABLES = ("reg_equipment", "reg_calibrations", "reg_deviations", "reg_settings",
               "reg_certificates", "reg_revisions", "reg_audit", "reg_audit_head",
               "reg_runs", "reg_run_events", "register_alembic_version")

#: what `bench register init --X-role ROLE` grants (docs/register.md, trust model)
ROLE_KINDS = ("service", "bench", "station")


def quote(role: str) -> str:
    return '"' + role.replace('"', '""') + '"'


def read_grants(role: str) -> list[str]:
    """A bench's or the station's role: read the register, but never a password hash, and
    run none of its functions: allocating, issuing and the audit trail are the service's
    (issue 53: the benches' role forged issues through reg_issue)."""
    from bench.app.register.schema import ACCOUNT_PUBLIC

    q = quote(role)
    return [
        f"GRANT USAGE ON SCHEMA public TO {q}",
        f"GRANT SELECT ({', '.join(ACCOUNT_PUBLIC)}) ON reg_accounts TO {q}",
        f"GRANT SELECT ON {', '.join(READ_TABLES)} TO {q}",
    ]


def service_grants(role: str) -> list[str]:
    """The register service's role (`bench register serve`): the one role besides the owner
    that checks passwords, changes accounts and equipment, allocates, issues and appends."""
    q = quote(role)
    return [
        f"GRANT USAGE ON SCHEMA public TO {q}",
        f"GRANT SELECT ON reg_accounts, {', '.join(READ_TABLES)} TO {q}",
        f"GRANT SELECT, INSERT, UPDATE, DELETE ON {', '.join(SERVICE_WRITES)} TO {q}",
        # withdrawing marks a revision; nothing else of it changes (issue 55)
        f"GRANT UPDATE (withdrawn_utc, withdrawn_reason, withdrawn_by) ON reg_revisions "
        f"TO {q}",
        # a run's record is added and completed, never deleted (issue 54)
        f"GRANT INSERT, UPDATE ON reg_runs TO {q}",
        f"GRANT INSERT ON reg_run_events TO {q}",
        f"GRANT USAGE ON ALL SEQUENCES IN SCHEMA public TO {q}",
        *(f"GRANT EXECUTE ON FUNCTION {f} TO {q}" for f in FUNCTION_SIGNATURES),
    ]


def grants(kind: str, role: str) -> list[str]:
    if kind == "service":
        return service_grants(role)
    if kind in ("bench", "station"):
        return read_grants(role)
    raise ValueError(f"role kind {kind!r}: one of {', '.join(ROLE_KINDS)}")


#: g0002: the roles an earlier register granted too much (EXECUTE on the functions, every
#: column of the accounts) lose it; their owner grants the service role anew
REVOKE_EARLIER = r"""
DO $$
DECLARE g record;
BEGIN
  FOR g IN SELECT DISTINCT grantee FROM information_schema.role_routine_grants
            WHERE routine_name IN ('reg_audit_append', 'reg_allocate', 'reg_issue')
              AND grantee <> current_user AND grantee <> 'PUBLIC' LOOP
    EXECUTE format('REVOKE EXECUTE ON FUNCTION reg_audit_append(text, text, text, text), '
                   'reg_allocate(text, text, text), reg_issue(text, int, text, text, text, '
                   'text, text, text, text, text, text) FROM %I', g.grantee);
  END LOOP;
  FOR g IN SELECT DISTINCT grantee FROM information_schema.role_table_grants
            WHERE table_name = 'reg_accounts' AND grantee <> current_user
              AND grantee <> 'PUBLIC' LOOP
    EXECUTE format('REVOKE ALL ON reg_accounts FROM %I', g.grantee);
    EXECUTE format('GRANT SELECT (name, full_name, roles, function, active, created_utc, '
                   'created_by, must_change, password_changed_utc) ON reg_accounts TO %I',
                   g.grantee);
  END LOOP;
END $$;
"""


def grants_like_inventory(readers: str, writers: str) -> str:
    """A migration's grants on new tables to the roles an earlier register made: those
    that read the inventory run `readers`, the one that writes it (the service) runs
    `writers`; each a semicolon-separated list of GRANT ... TO %I statements."""
    def each(sqls: str) -> str:
        return "\n".join(f"      EXECUTE format('{q.strip()}', g.grantee);"
                         for q in sqls.split(";") if q.strip())

    return f"""
DO $$
DECLARE g record;
BEGIN
  FOR g IN SELECT DISTINCT grantee, privilege_type FROM information_schema.role_table_grants
            WHERE table_name = 'reg_equipment' AND grantee <> current_user
              AND privilege_type IN ('SELECT', 'INSERT') LOOP
    IF g.privilege_type = 'SELECT' THEN
{each(readers)}
    ELSE
{each(writers)}
    END IF;
  END LOOP;
END $$;
"""
