"""The lab's records database (SPEC.md section 9): sensors, reference standards, stands, runs,
a certificate register and an append-only audit trail.

The run folders (app.records.run_folder) stay the primary raw record; the database indexes them
by their
manifest hash and holds what a lab manages around them. SQLAlchemy 2 (typed ORM) over an
embedded SQLite file by default, PostgreSQL (psycopg 3) by URL; the schema is created and
migrated by Alembic only (`accelcal db upgrade`), never implicitly.
"""
