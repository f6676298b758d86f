PRAGMA foreign_keys=OFF;
BEGIN TRANSACTION;
CREATE TABLE register_alembic_version (
	version_num VARCHAR(32) NOT NULL, 
	CONSTRAINT register_alembic_version_pkc PRIMARY KEY (version_num)
);
INSERT INTO register_alembic_version VALUES('g0004');
CREATE TABLE reg_accounts (
	name VARCHAR(120) NOT NULL, 
	full_name VARCHAR(200) NOT NULL, 
	roles VARCHAR(200) NOT NULL, 
	function VARCHAR(200), 
	password_hash TEXT NOT NULL, 
	active BOOLEAN DEFAULT 1 NOT NULL, 
	created_utc VARCHAR(40) NOT NULL, 
	created_by VARCHAR(120), 
	must_change BOOLEAN DEFAULT 0 NOT NULL, 
	password_changed_utc VARCHAR(40), 
	PRIMARY KEY (name)
);
INSERT INTO reg_accounts VALUES('admin','R. Admin','admin',NULL,'$argon2id$v=19$m=65536,t=3,p=4$l/MjTb8oLU2j8YiT1WlaZA$DJvPlMxtm2SKqKvO8bSxbvuG7NHstzVz2/2XjlVoWZE',1,'2026-11-29T21:54:09.903523Z','admin',0,'2026-11-29T21:54:09.903523Z');
INSERT INTO reg_accounts VALUES('P. Petrov','P. Petrov','reviewer,signatory','Technical manager','$argon2id$v=19$m=65536,t=3,p=4$XRKPIJa5Zg31lyWe5icjWQ$gD1pOUMlO26DsUYFo5WT7ua7JNSBBi75ZenAqvVDKCE',1,'2026-11-29T21:54:11.272576Z','admin',0,'2026-11-29T21:54:12.613044Z');
INSERT INTO reg_accounts VALUES('Q. Manager','Q. Manager','quality',NULL,'$argon2id$v=19$m=65536,t=3,p=4$6aMgcrGSWyTG44s4NCEWcg$8AAh1ywDXd5tF2hzH8cZvgKksiNsTLCaZqax8ZtNqZA',1,'2026-11-29T21:54:13.092031Z','admin',1,'2026-11-29T21:54:13.092031Z');
CREATE TABLE reg_logins (
	name VARCHAR(120) NOT NULL, 
	failures INTEGER NOT NULL, 
	first_failure_utc VARCHAR(40), 
	locked_until_utc VARCHAR(40), 
	PRIMARY KEY (name)
);
CREATE TABLE reg_equipment (
	serial VARCHAR(120) NOT NULL, 
	model VARCHAR(200) NOT NULL, 
	certificate VARCHAR(200), 
	issuer VARCHAR(200), 
	due_date VARCHAR(10), 
	added_utc VARCHAR(40) NOT NULL, 
	added_by VARCHAR(120) NOT NULL, 
	identity_only BOOLEAN DEFAULT 0 NOT NULL, 
	PRIMARY KEY (serial)
);
INSERT INTO reg_equipment VALUES('C-1','counter','CAL-2','Lab B','2028-01-02','2026-11-29T21:54:13.201237Z','Q. Manager',0);
INSERT INTO reg_equipment VALUES('F-1','fixture',NULL,NULL,NULL,'2026-11-29T21:54:13.228047Z','Q. Manager',1);
CREATE TABLE reg_settings (
	"key" VARCHAR(80) NOT NULL, 
	value TEXT NOT NULL, 
	PRIMARY KEY ("key")
);
INSERT INTO reg_settings VALUES('issuer.prefix','RT');
INSERT INTO reg_settings VALUES('lockout_attempts','7');
CREATE TABLE reg_certificates (
	number VARCHAR(80) NOT NULL, 
	seq INTEGER NOT NULL, 
	run_uid VARCHAR(64) NOT NULL, 
	allocated_utc VARCHAR(40) NOT NULL, 
	PRIMARY KEY (number), 
	UNIQUE (seq), 
	UNIQUE (run_uid)
);
INSERT INTO reg_certificates VALUES('RT-2026-00001',1,'run-1','2026-11-29T21:54:13Z');
CREATE TABLE reg_audit (
	seq INTEGER NOT NULL, 
	utc VARCHAR(40) NOT NULL, 
	actor VARCHAR(120) NOT NULL, 
	action VARCHAR(60) NOT NULL, 
	object TEXT NOT NULL, 
	detail TEXT NOT NULL, 
	db_user VARCHAR(120) NOT NULL, 
	prev_digest VARCHAR(64) NOT NULL, 
	digest VARCHAR(64) NOT NULL, 
	PRIMARY KEY (seq), 
	UNIQUE (prev_digest)
);
INSERT INTO reg_audit VALUES(1,'2026-11-29T21:54:09.911507Z','admin','account added','admin','{"full_name": "R. Admin", "function": null, "password_to_change": false, "roles": ["admin"]}','root','0000000000000000000000000000000000000000000000000000000000000000','d17298a3d5055ba2cf1c5768cb517bb87fceca1ae1cdfff8ba834a1f5777beaf');
INSERT INTO reg_audit VALUES(2,'2026-11-29T21:54:10.563563Z','admin','authenticated','admin','{"role": "admin"}','root','d17298a3d5055ba2cf1c5768cb517bb87fceca1ae1cdfff8ba834a1f5777beaf','5a1799b82a2d4c928c1418de6c06be5a2cc06c53bb89f282a84d032577c5379e');
INSERT INTO reg_audit VALUES(3,'2026-11-29T21:54:11.274486Z','admin','account added','P. Petrov','{"full_name": "P. Petrov", "function": "Technical manager", "password_to_change": true, "roles": ["signatory"]}','root','5a1799b82a2d4c928c1418de6c06be5a2cc06c53bb89f282a84d032577c5379e','1ece0c24369d958d98f18f74251c924d7d11b07c541280078c152985c8ce76ff');
INSERT INTO reg_audit VALUES(4,'2026-11-29T21:54:11.955060Z','P. Petrov','authenticated','P. Petrov','{"role": null}','root','1ece0c24369d958d98f18f74251c924d7d11b07c541280078c152985c8ce76ff','2477bfb42a6918519f41d44773773b228a2b9196cd1c16152d1870bbae97983f');
INSERT INTO reg_audit VALUES(5,'2026-11-29T21:54:12.615717Z','P. Petrov','password changed','P. Petrov','{"new": "own password", "old": "password set by an admin"}','root','2477bfb42a6918519f41d44773773b228a2b9196cd1c16152d1870bbae97983f','6a2687ff748b883685d6a8b6eb60c194a1576ec7f8d7dd7c89c9e10146e99e37');
INSERT INTO reg_audit VALUES(6,'2026-11-29T21:54:13.093755Z','admin','account added','Q. Manager','{"full_name": "Q. Manager", "function": null, "password_to_change": true, "roles": ["quality"]}','root','6a2687ff748b883685d6a8b6eb60c194a1576ec7f8d7dd7c89c9e10146e99e37','c7197cb3b229f88bcef8c12a0110f03f1d5d285ace110864da3faa5d0736e52f');
INSERT INTO reg_audit VALUES(7,'2026-11-29T21:54:13.119306Z','admin','setting changed','issuer.prefix','{"new": "RT", "old": null}','root','c7197cb3b229f88bcef8c12a0110f03f1d5d285ace110864da3faa5d0736e52f','4dd5bf1b50c1b9ac803b3fa15e3be5f225e4c7368975e64099d8eb2e2866b89a');
INSERT INTO reg_audit VALUES(8,'2026-11-29T21:54:13.150189Z','admin','setting changed','lockout_attempts','{"new": "7", "old": "5 (default)"}','root','4dd5bf1b50c1b9ac803b3fa15e3be5f225e4c7368975e64099d8eb2e2866b89a','ec72ff5275c60b1436e148ae6a5919ce54c38c9c220c99e8252513666f6a42cb');
INSERT INTO reg_audit VALUES(9,'2026-11-29T21:54:13.175420Z','admin','role granted','P. Petrov','{"new": ["reviewer", "signatory"], "old": ["signatory"], "role": "reviewer"}','root','ec72ff5275c60b1436e148ae6a5919ce54c38c9c220c99e8252513666f6a42cb','b379883a4db3d674dbe99f3af26aa7c58f6dd667e72ed425fde432579a3c2f7a');
INSERT INTO reg_audit VALUES(10,'2026-11-29T21:54:13.210150Z','Q. Manager','equipment added','C-1','{"certificate": "CAL-1", "due": "2026-06-01", "identity_only": false, "issuer": "Lab A", "model": "counter"}','root','b379883a4db3d674dbe99f3af26aa7c58f6dd667e72ed425fde432579a3c2f7a','7e7ece0b3354c4b9c63caa35855f55fec0f4361c80092e90eb2a76d297151004');
INSERT INTO reg_audit VALUES(11,'2026-11-29T21:54:13.229754Z','Q. Manager','equipment added','F-1','{"certificate": null, "due": null, "identity_only": true, "issuer": null, "model": "fixture"}','root','7e7ece0b3354c4b9c63caa35855f55fec0f4361c80092e90eb2a76d297151004','db98c80f81fa314930d818d5311ae7af3b83b81b88c1a66c71544a149cf550fd');
INSERT INTO reg_audit VALUES(12,'2026-11-29T21:54:13.265163Z','Q. Manager','deviation recorded','C-1','{"expires": "2026-12-09", "reason": "used while the new certificate is awaited"}','root','db98c80f81fa314930d818d5311ae7af3b83b81b88c1a66c71544a149cf550fd','f86e18ef9bfb4ba4cef6bb27744552740043b17ddbdde876136a964acd9647ae');
INSERT INTO reg_audit VALUES(13,'2026-11-29T21:54:13.282896Z','Q. Manager','deviation revoked','C-1','{"revoked": 1}','root','f86e18ef9bfb4ba4cef6bb27744552740043b17ddbdde876136a964acd9647ae','d397878d50611a8ad61a731b7c76c3b619ba4e4463b1862c219ff5a179c6c93b');
INSERT INTO reg_audit VALUES(14,'2026-11-29T21:54:13.306451Z','Q. Manager','equipment recalibrated','C-1','{"as_found": {"error": 1.5e-05, "error_U": 2.5e-06, "found": "out"}, "new": {"calibrated_on": "2026-07-01", "certificate": "CAL-2", "due": "2028-01-02", "issuer": "Lab B"}, "old": {"certificate": "CAL-1", "due": "2026-06-01", "issuer": "Lab A"}}','root','d397878d50611a8ad61a731b7c76c3b619ba4e4463b1862c219ff5a179c6c93b','f785886f63469e8e6207c7e29f6302965aa71018daa2589a10ac0718dc0d56ae');
INSERT INTO reg_audit VALUES(15,'2026-11-29T21:54:13.327191Z','P. Petrov','run registered','run-1','{"bench": "hall-1", "inputs": {"procedure.yaml": "eeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeee", "stand.yaml": "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffff"}, "performer": "P. Petrov", "simulated": true, "version": "0.1"}','root','f785886f63469e8e6207c7e29f6302965aa71018daa2589a10ac0718dc0d56ae','1c53134b5e8d7ee03741f55faa4b84373b520bd906c7fcdb3175d815f0821203');
INSERT INTO reg_audit VALUES(16,'2026-11-29T21:54:13.364282Z','bench','run resumed','run-1','{"performer": null, "session": 2, "via": "this bench"}','root','1c53134b5e8d7ee03741f55faa4b84373b520bd906c7fcdb3175d815f0821203','1877d78c74e3c3c3ff98e6756a31cdcb219d72f532e56977debd994c5714cb91');
INSERT INTO reg_audit VALUES(17,'2026-11-29T21:54:13.393056Z','bench hall-1','run session result','run-1','{"raw_captures": 1, "reason": null, "result_sha256": "914ae6e17482ca08cfa2954cd87bbef96f8028e48b0a3d0ee375d85d26833193", "via": "this bench"}','root','1877d78c74e3c3c3ff98e6756a31cdcb219d72f532e56977debd994c5714cb91','20b1816454ca8bbb55662d3b55f4b85eec3dc044b0b70e7c83fda2dc6a2aa799');
INSERT INTO reg_audit VALUES(18,'2026-11-29T21:54:13.410990Z','bench hall-1','run analysis result','run-1','{"raw_captures": 2, "reason": "re-analysed: \u00fcn\u00efcode reason", "result_sha256": "914ae6e17482ca08cfa2954cd87bbef96f8028e48b0a3d0ee375d85d26833193", "via": "this bench"}','root','20b1816454ca8bbb55662d3b55f4b85eec3dc044b0b70e7c83fda2dc6a2aa799','abf77559c7f25312a3bb94643d03c5b67a3107a326a18d62daad3174534babbb');
INSERT INTO reg_audit VALUES(19,'2026-11-29T21:54:13.895577Z','P. Petrov','authenticated','P. Petrov','{"role": "signatory"}','root','abf77559c7f25312a3bb94643d03c5b67a3107a326a18d62daad3174534babbb','20885367fff39c1b15b12ae9dd6cbf509e72154c25728987a1c304a2d62a11ef');
INSERT INTO reg_audit VALUES(20,'2026-11-29T21:54:13.923572Z','P. Petrov','number allocated','RT-2026-00001','run run-1','root','20885367fff39c1b15b12ae9dd6cbf509e72154c25728987a1c304a2d62a11ef','6d81713d4f2d3e54342f2c89df60d98bd1794912f07f2ae8eb54e4dfb9c77e86');
INSERT INTO reg_audit VALUES(21,'2026-11-29T21:54:13.944715Z','P. Petrov','issue begun','RT-2026-00001 revision 1','{"issued_utc": "2026-11-29T21:54:13Z", "result_sha256": "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa"}','root','6d81713d4f2d3e54342f2c89df60d98bd1794912f07f2ae8eb54e4dfb9c77e86','80d4df5c47ed2b7864fed89274c57b747b9166e13a3b88d3f0817a197944991b');
INSERT INTO reg_audit VALUES(22,'2026-11-29T21:54:13.960100Z','P. Petrov','issue','RT-2026-00001 revision 1','{"bench": "hall-1", "list": [1, 2.5, null, "\u00e9"], "run_dir": "run-1", "run_uid": "run-1", "signatory": "P. Petrov", "x": 1e-05}','root','80d4df5c47ed2b7864fed89274c57b747b9166e13a3b88d3f0817a197944991b','8e25056035554da8d2c9724be45b4ed1e2f46ec8f6bfeddd006d57b197040176');
INSERT INTO reg_audit VALUES(23,'2026-11-29T21:54:13.988280Z','Q. Manager','withdrawn','RT-2026-00001 revision 1','{"reason": "withdrawn for the stored bytes test of the register"}','root','8e25056035554da8d2c9724be45b4ed1e2f46ec8f6bfeddd006d57b197040176','93c5141710bd3b23bee2a0bb01d47adc579140b154c8ea9f69f126fd415639af');
INSERT INTO reg_audit VALUES(24,'2026-11-29T21:54:14.005579Z','P. Petrov','station login','P. Petrov','{"at": "station", "remote": "::1"}','root','93c5141710bd3b23bee2a0bb01d47adc579140b154c8ea9f69f126fd415639af','941d0f8801177c4d7eff0ffae3e9539ea81d0a1d0bd041d783e81873092e79ca');
INSERT INTO reg_audit VALUES(25,'2026-11-29T21:54:14.024543Z','P. Petrov','control review','run-1','a plain text detail','root','941d0f8801177c4d7eff0ffae3e9539ea81d0a1d0bd041d783e81873092e79ca','0b459fe3f6e3c1f56c2f282390d0d67bfa92c1b4124942f59469c5886f9a15d2');
INSERT INTO reg_audit VALUES(26,'2026-11-29T21:54:14.046406Z','Q. Manager','impact assessed','C-1','{"finding": {"error": 1e-05, "serial": "C-1"}, "runs": [{"shift": null, "uid": "run-1"}]}','root','0b459fe3f6e3c1f56c2f282390d0d67bfa92c1b4124942f59469c5886f9a15d2','a3d056f68a38b6ca30a764e017979cf854437771551e1b1a90e3b1dbbb36aa25');
CREATE TABLE reg_audit_head (
	id INTEGER NOT NULL, 
	seq INTEGER NOT NULL, 
	digest VARCHAR(64) NOT NULL, 
	PRIMARY KEY (id)
);
INSERT INTO reg_audit_head VALUES(1,26,'a3d056f68a38b6ca30a764e017979cf854437771551e1b1a90e3b1dbbb36aa25');
CREATE TABLE reg_runs (
	uid VARCHAR(64) NOT NULL, 
	bench VARCHAR(200) NOT NULL, 
	performer VARCHAR(120), 
	version VARCHAR(60) NOT NULL, 
	simulated BOOLEAN NOT NULL, 
	inputs TEXT NOT NULL, 
	items TEXT NOT NULL, 
	registered_utc VARCHAR(40) NOT NULL, 
	via VARCHAR(200) NOT NULL, 
	result_sha256 VARCHAR(64), 
	result TEXT, 
	result_utc VARCHAR(40), 
	raw TEXT NOT NULL, 
	PRIMARY KEY (uid)
);
INSERT INTO reg_runs VALUES('run-1','hall-1','P. Petrov','0.1',1,'{"procedure.yaml": "eeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeee", "stand.yaml": "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffff"}','[{"calibrated_on": "2026-01-02", "certificate": "CAL-1", "deviation": null, "due": "2027-01-02", "issuer": "Lab A", "item": "counter", "problem": null, "serial": "C-1", "where": "stand"}, {"deviation": null, "identity_only": "yes", "item": "fixture", "problem": null, "serial": null, "where": "stand"}]','2026-11-29T21:54:13.324018Z','bench hall-1','914ae6e17482ca08cfa2954cd87bbef96f8028e48b0a3d0ee375d85d26833193',replace('{"schema": "bench.result/1", "stand": {"simulated": true}, "x": 1e-05}\n','\n',char(10)),'2026-11-29T21:54:13.409878Z','{"raw/s1/fog.bin": "1111111111111111111111111111111111111111111111111111111111111111", "raw/s2/fog.bin": "2222222222222222222222222222222222222222222222222222222222222222"}');
CREATE TABLE reg_calibrations (
	id INTEGER NOT NULL, 
	serial VARCHAR(120) NOT NULL, 
	certificate VARCHAR(200) NOT NULL, 
	issuer VARCHAR(200) NOT NULL, 
	calibrated_on VARCHAR(10), 
	due_date VARCHAR(10) NOT NULL, 
	found VARCHAR(3), 
	found_error FLOAT, 
	found_error_u FLOAT, 
	recorded_utc VARCHAR(40) NOT NULL, 
	recorded_by VARCHAR(120) NOT NULL, 
	PRIMARY KEY (id), 
	FOREIGN KEY(serial) REFERENCES reg_equipment (serial)
);
INSERT INTO reg_calibrations VALUES(1,'C-1','CAL-1','Lab A','2025-06-01','2026-06-01',NULL,NULL,NULL,'2026-11-29T21:54:13.203206Z','Q. Manager');
INSERT INTO reg_calibrations VALUES(2,'C-1','CAL-2','Lab B','2026-07-01','2028-01-02','out',1.5000000000000000379e-05,2.5000000000000002042e-06,'2026-11-29T21:54:13.305331Z','Q. Manager');
CREATE TABLE reg_deviations (
	id INTEGER NOT NULL, 
	serial VARCHAR(120) NOT NULL, 
	reason TEXT NOT NULL, 
	expires VARCHAR(10) NOT NULL, 
	recorded_by VARCHAR(120) NOT NULL, 
	recorded_utc VARCHAR(40) NOT NULL, 
	revoked_utc VARCHAR(40), 
	revoked_by VARCHAR(120), 
	PRIMARY KEY (id), 
	FOREIGN KEY(serial) REFERENCES reg_equipment (serial)
);
INSERT INTO reg_deviations VALUES(1,'C-1','used while the new certificate is awaited','2026-12-09','Q. Manager','2026-11-29T21:54:13.259665Z','2026-11-29T21:54:13.281525Z','Q. Manager');
CREATE TABLE reg_revisions (
	id INTEGER NOT NULL, 
	number VARCHAR(80) NOT NULL, 
	revision INTEGER NOT NULL, 
	issued_utc VARCHAR(40) NOT NULL, 
	signatory VARCHAR(120) NOT NULL, 
	signatory_name VARCHAR(200) NOT NULL, 
	meaning VARCHAR(200) NOT NULL, 
	reason TEXT, 
	result_sha256 VARCHAR(64) NOT NULL, 
	pdf_sha256 VARCHAR(64) NOT NULL, 
	dcc_sha256 VARCHAR(64) NOT NULL, 
	html_sha256 VARCHAR(64) NOT NULL, 
	withdrawn_utc VARCHAR(40), 
	audit_digest VARCHAR(64), 
	withdrawn_reason TEXT, 
	withdrawn_by VARCHAR(120), 
	PRIMARY KEY (id), 
	CONSTRAINT reg_revisions_number_revision UNIQUE (number, revision), 
	FOREIGN KEY(number) REFERENCES reg_certificates (number), 
	FOREIGN KEY(signatory) REFERENCES reg_accounts (name)
);
INSERT INTO reg_revisions VALUES(1,'RT-2026-00001',1,'2026-11-29T21:54:13Z','P. Petrov','P. Petrov','authorised for issue',NULL,'aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa','bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb','cccccccccccccccccccccccccccccccccccccccccccccccccccccccccccccccc','dddddddddddddddddddddddddddddddddddddddddddddddddddddddddddddddd','2026-11-29T21:54:13Z','8e25056035554da8d2c9724be45b4ed1e2f46ec8f6bfeddd006d57b197040176','withdrawn for the stored bytes test of the register','Q. Manager');
CREATE TABLE reg_run_events (
	id INTEGER NOT NULL, 
	uid VARCHAR(64) NOT NULL, 
	utc VARCHAR(40) NOT NULL, 
	kind VARCHAR(20) NOT NULL, 
	detail TEXT NOT NULL, 
	PRIMARY KEY (id), 
	FOREIGN KEY(uid) REFERENCES reg_runs (uid)
);
INSERT INTO reg_run_events VALUES(1,'run-1','2026-11-29T21:54:13.324018Z','start','{"via": "bench hall-1"}');
INSERT INTO reg_run_events VALUES(2,'run-1','2026-11-29T21:54:13.363397Z','resume','{"session": 2, "performer": null, "via": "this bench"}');
INSERT INTO reg_run_events VALUES(3,'run-1','2026-11-29T21:54:13.385920Z','session','{"result_sha256": "914ae6e17482ca08cfa2954cd87bbef96f8028e48b0a3d0ee375d85d26833193", "raw_captures": 1, "reason": null, "via": "this bench"}');
INSERT INTO reg_run_events VALUES(4,'run-1','2026-11-29T21:54:13.409878Z','analysis','{"result_sha256": "914ae6e17482ca08cfa2954cd87bbef96f8028e48b0a3d0ee375d85d26833193", "raw_captures": 2, "reason": "re-analysed: \u00fcn\u00efcode reason", "via": "this bench"}');
CREATE TRIGGER reg_audit_no_update BEFORE UPDATE ON reg_audit
       BEGIN SELECT RAISE(ABORT, 'the audit trail is append-only'); END;
CREATE TRIGGER reg_audit_no_delete BEFORE DELETE ON reg_audit
       BEGIN SELECT RAISE(ABORT, 'the audit trail is append-only'); END;
CREATE TRIGGER reg_revisions_no_delete BEFORE DELETE ON reg_revisions
       BEGIN SELECT RAISE(ABORT, 'an issued revision is never removed'); END;
CREATE TRIGGER reg_revisions_only_withdrawn BEFORE UPDATE ON reg_revisions
       WHEN OLD.withdrawn_utc IS NOT NULL OR NEW.number IS NOT OLD.number
            OR NEW.revision IS NOT OLD.revision OR NEW.pdf_sha256 IS NOT OLD.pdf_sha256
            OR NEW.dcc_sha256 IS NOT OLD.dcc_sha256 OR NEW.signatory IS NOT OLD.signatory
            OR NEW.result_sha256 IS NOT OLD.result_sha256
       BEGIN SELECT RAISE(ABORT, 'an issued revision is only ever marked withdrawn'); END;
CREATE TRIGGER reg_certificates_no_delete BEFORE DELETE ON reg_certificates
       BEGIN SELECT RAISE(ABORT, 'an allocated number is never removed'); END;
COMMIT;
