"""The customer portal of the web view (issue 35 point 5): a customer account (created by staff,
app.web.accounts) signs in at /portal/login and sees only its own customer's certificates (PDF
and DCC downloads) and sensors with their due dates (CSV and iCalendar exports).

Access rules:
- a portal session lives in its own server-side store under its own cookie key ("portal"); the
  staff guard reads only "sid" from the staff store, so a customer session is never a staff
  one, whatever the cookie says (and the cookie is signed: a tampered one is no session);
- the account is read from the records at every request: disabled, removed or given a new
  password, its sessions end; the customer it is bound to is the records', never the
  session's;
- every query is filtered by that customer in SQL, and anything not the customer's is answered
  404 with the same words as something that does not exist (no 403, no redirect that would
  confirm it exists); documents are served from the register's paths, never from the URL.
"""

from __future__ import annotations

import logging
import math
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any
from urllib.parse import quote

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import RedirectResponse, Response
from starlette.routing import Route

from app.web.documents import (
    DocumentError,
    certificate_dcc,
    certificate_pdf,
    certificate_pdf_bytes,
)
from app.web.guard import CheckSlots, SessionStore, Throttle, client_address, password_stamp
from app.web.store import PortalAccount, Store
from app.web.users import signed_in

log = logging.getLogger(__name__)

SESSION_KEY = "portal"  # the cookie's key of a portal session id (the staff's is "sid")
HOME = "/portal"
NOT_FOUND = "Not found in your records."  # one answer for what is not there or not yours


@dataclass(frozen=True)
class PortalDeps:
    """What the portal shares with the staff pages: the records, the page renderer
    (request, template, status, context), the form token, the argon2 check slots, the
    trusted proxies, the refusal page (request, target, message, wait s, sign-in path) of a
    throttled sign-in, the portal's sessions and throttle, and the lab's host name."""

    store: Store
    page: Callable[..., Response]
    csrf: Callable[[Request], str]
    slots: CheckSlots
    proxies: tuple[str, ...]
    refused: Callable[[Request, str, str, float, str], Response]
    sessions: SessionStore
    throttle: Throttle
    lab_host: str | None = None  # the --verify-url's host: the calendar UIDs' (else the request's)


def _local(target: str) -> str:
    """`target` when it is a portal path on this site, else the portal's home (no open
    redirect, and no way into a staff page from the portal's sign-in)."""
    if (target == HOME or target.startswith(HOME + "/")) and "\\" not in target:
        return target
    return HOME


def _check(store: Store, username: str, password: str) -> PortalAccount | None:
    """The active account `username` when `password` is its own, else None."""
    return signed_in(store.account(username) if username else None, password)


def _filename(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in text)


def portal_routes(deps: PortalDeps) -> list[Route]:
    """The portal's routes (sign-in, home, sensor, documents, exports)."""
    store, sessions, throttle = deps.store, deps.sessions, deps.throttle

    def current(request: Request) -> PortalAccount | None:
        """The signed-in account, still active, with its password unchanged; else None (and
        its sessions end)."""
        sid = request.session.get(SESSION_KEY)
        held = sessions.get(sid) if isinstance(sid, str) else None
        if held is None:
            return None
        account = store.account(held.username)
        if (
            account is None
            or not account.active
            or password_stamp(account.password_hash) != held.stamp
        ):
            ended = sessions.revoke_user(held.username)
            log.info("portal: %d session(s) of %s ended", ended, held.username)
            request.session.pop(SESSION_KEY, None)
            return None
        return account

    def page(request: Request, name: str, status: int = 200, **context: Any) -> Response:
        return deps.page(request, name, status, user=None, **context)

    def not_found(request: Request, account: PortalAccount) -> Response:
        return page(
            request, "message.html", 404, title="Not found", message=NOT_FOUND, portal=account
        )

    def customer(endpoint: Callable[[Request, PortalAccount], Response]) -> Callable[..., Response]:
        """Only for a signed-in, active customer account; else to the portal's sign-in."""

        def guarded(request: Request) -> Response:
            account = current(request)
            if account is None:
                target = request.url.path + (f"?{request.url.query}" if request.url.query else "")
                return RedirectResponse(f"/portal/login?next={quote(target, safe='')}", 303)
            return endpoint(request, account)

        return guarded

    def login(request: Request) -> Response:
        target = _local(request.query_params.get("next", HOME))
        return page(request, "portal_login.html", target=target, error=None)

    async def login_post(request: Request) -> Response:
        form = await request.form()
        username = str(form.get("username", "")).strip()[:100]
        password = str(form.get("password", ""))[:1000]
        target = _local(str(form.get("next", HOME)))
        if not secrets.compare_digest(str(form.get("csrf", "")), deps.csrf(request)):
            error = "Form expired: retry."
            return page(request, "portal_login.html", 400, target=target, error=error)
        peer = request.client.host if request.client else None
        client = client_address(peer, request.headers.getlist("x-forwarded-for"), deps.proxies)
        if not deps.slots.take():
            message = "The server is busy checking other sign-ins: retry in a few seconds."
            return deps.refused(request, target, message, 1.0, "/portal/login")
        try:
            verdict = throttle.attempt(username, client)
            if not verdict.allowed:
                log.warning("portal: sign-in of %r from %s refused: wait", username, client)
                wait = math.ceil(verdict.wait_s)
                message = f"Too many sign-in attempts: wait {wait} s and retry."
                return deps.refused(request, target, message, verdict.wait_s, "/portal/login")
            account = await run_in_threadpool(_check, store, username, password)
        finally:
            deps.slots.give()
        if account is None:
            throttle.failed(username, client)
            log.info("portal: failed sign-in of %r from %s", username, client)
            error = "Unknown user name or wrong password."
            return page(request, "portal_login.html", 401, target=target, error=error)
        throttle.succeeded(username, client)
        old = request.session.get(SESSION_KEY)
        if isinstance(old, str):
            sessions.revoke(old)
        request.session.clear()  # a new session: no staff session rides along with it
        request.session[SESSION_KEY] = sessions.open(
            account.username, account.display_name, account.password_hash
        )
        log.info("portal: %s (%s) signed in from %s", account.username, account.customer, client)
        return RedirectResponse(target, 303)

    async def logout(request: Request) -> Response:
        form = await request.form()
        if secrets.compare_digest(str(form.get("csrf", "")), deps.csrf(request)):
            sid = request.session.get(SESSION_KEY)
            if isinstance(sid, str):
                sessions.revoke(sid)
            request.session.clear()
        return RedirectResponse("/portal/login", 303)

    def home(request: Request, account: PortalAccount) -> Response:
        today = datetime.now(UTC).date()
        return page(
            request,
            "portal.html",
            portal=account,
            rows=store.customer_certificates(account.customer_id),
            sensors=store.customer_sensors(account.customer_id),
            today=today,
        )

    def sensor(request: Request, account: PortalAccount) -> Response:
        serial = request.path_params["serial"]
        found = store.customer_sensors(account.customer_id, serial)
        if not found:
            return not_found(request, account)
        return page(
            request,
            "portal_sensor.html",
            portal=account,
            sensor=found[0],
            rows=store.customer_sensor_certificates(account.customer_id, serial),
            today=datetime.now(UTC).date(),
        )

    def document(request: Request, account: PortalAccount) -> Response:
        number, kind = request.path_params["number"], request.path_params["kind"]
        row = store.customer_certificate(account.customer_id, number)
        if kind not in ("pdf", "xml") or row is None:
            return not_found(request, account)
        try:
            if kind == "pdf":
                data = certificate_pdf_bytes(row.number, row.file, row.sha256)
                media = "application/pdf"
            else:
                pdf = certificate_pdf(row.number, row.file, row.sha256)
                data = certificate_dcc(row.number, pdf, row.dcc_sha256)
                media = "application/xml"
        except DocumentError as exc:  # the lab's problem: logged, not shown (paths)
            log.warning("portal: %s asked for %s.%s: %s", account.username, number, kind, exc)
            return page(
                request,
                "message.html",
                404,
                title="Not available",
                message=f"The {kind.upper()} of certificate {row.number} cannot be served now; "
                "please contact the laboratory.",
                portal=account,
            )
        disposition = f'attachment; filename="{_filename(row.number)}.{kind}"'
        return Response(data, media_type=media, headers={"content-disposition": disposition})

    def export(request: Request, account: PortalAccount) -> Response:
        from app.web.due_export import due_csv, due_ical

        kind = request.path_params["kind"]
        if kind not in ("csv", "ics"):
            return not_found(request, account)
        items = store.customer_sensors(account.customer_id)
        name = f"calibrations-due-{_filename(account.customer)}.{kind}"
        headers = {"content-disposition": f'attachment; filename="{name}"'}
        if kind == "csv":
            body = due_csv(items, datetime.now(UTC).date()).encode("utf-8")
            return Response(body, media_type="text/csv; charset=utf-8", headers=headers)
        lab = deps.lab_host or request.url.hostname or "accelcal"
        body = due_ical(items, lab=lab, customer=account.customer)
        return Response(body, media_type="text/calendar; charset=utf-8", headers=headers)

    return [
        Route("/portal/login", login, methods=["GET"]),
        Route("/portal/login", login_post, methods=["POST"]),
        Route("/portal/logout", logout, methods=["POST"]),
        Route("/portal", customer(home)),
        Route("/portal/due.{kind:str}", customer(export)),
        Route("/portal/certificates/{number:path}/certificate.{kind:str}", customer(document)),
        Route("/portal/sensors/{serial:path}", customer(sensor)),
        Route("/portal/{rest:path}", customer(lambda r, a: not_found(r, a))),
    ]
