"""The lab's read-only web view over the records database (issue 27, point 3): the register
with search, a certificate's page (PDF, DCC, verification), due lists, a sensor's history
chart, staff login, and the public verification page a certificate's QR code leads to.

Starlette with Jinja2 pages rendered on the server (no JavaScript); the database is opened
read-only (app.web.store). Start it with `python -m app.web --db URL --port N`.
"""
