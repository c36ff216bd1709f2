"""The web view's pages and routes (Starlette, Jinja2 templates rendered on the server).

Staff pages need a signed-in user: a session kept on the server (app.web.guard), whose random
id rides in a signed cookie with the form token; app.web.users for the passwords. Sign-in is
throttled per user name and per client (counted before the password is checked, a growing
back-off), at most PASSWORD_CHECKS_AT_ONCE argon2 checks run at once. The one public page,
/verify/NUMBER?code=CODE, shows only a certificate's status. Customers sign in to their own
portal under /portal (app.web.portal: their own certificates and due dates, nothing else).
Every response carries a strict Content-Security-Policy (no script at all) and no Referer.
"""

from __future__ import annotations

import base64
import html
import logging
import math
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import quote, urlsplit

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.middleware.sessions import SessionMiddleware
from starlette.requests import Request
from starlette.responses import HTMLResponse, RedirectResponse, Response
from starlette.routing import Route
from starlette.templating import Jinja2Templates
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.certificate.qr import QrError, qr_svg, verify_address
from app.records.db.lab import RecordsError
from app.web.chart import history_svg
from app.web.documents import (
    DocumentError,
    certificate_dcc,
    certificate_pdf,
    certificate_pdf_bytes,
    printed_verification_address,
    verify_certificate,
)
from app.web.guard import (
    PASSWORD_CHECKS_AT_ONCE,
    SESSION_MAX_AGE_S,
    CheckSlots,
    SessionStore,
    StaffSession,
    Throttle,
    client_address,
    password_stamp,
)
from app.web.portal import SESSION_KEY as PORTAL_SESSION_KEY
from app.web.portal import PortalDeps, portal_routes
from app.web.store import StaffUser, Store
from app.web.users import signed_in

log = logging.getLogger(__name__)

DUE_DAYS_DEFAULT, DUE_DAYS_MAX = 30, 3650
SECURITY_HEADERS = (
    (
        b"content-security-policy",
        b"default-src 'none'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
        b"form-action 'self'; frame-ancestors 'none'; base-uri 'none'",
    ),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"x-frame-options", b"DENY"),
)


class SecurityHeaders:
    """ASGI middleware adding SECURITY_HEADERS (and no-store caching) to every response."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                headers.extend(SECURITY_HEADERS)
                headers.append((b"cache-control", b"no-store"))
                message["headers"] = headers
            await send(message)

        await self.app(scope, receive, send_with_headers)


@dataclass(frozen=True)
class WebConfig:
    """How the web view runs: the session key, the base of verification addresses
    ([laboratory] verify_url; None: this server's own /verify), cookies only over HTTPS
    (asked for, or served over TLS), the lab's CA certificate that signatures must chain to
    (None: never "verified"), and the TLS-terminating proxies whose X-Forwarded-For is read
    (none: the header is ignored; any: cookies only over HTTPS)."""

    secret_key: str
    verify_url: str | None = None
    https_only: bool = False
    trust: Path | None = None
    proxies: tuple[str, ...] = ()

    @property
    def secure_cookie(self) -> bool:
        """Whether the session cookie is sent over HTTPS only (Secure)."""
        return self.https_only or bool(self.proxies)


def _templates() -> Jinja2Templates:
    folder = resources.files("app.web").joinpath("templates")
    templates = Jinja2Templates(directory=str(folder))
    templates.env.filters["mv"] = lambda v: "–" if v is None else f"{v:.5g}"
    templates.env.filters["when"] = lambda t: t.strftime("%Y-%m-%d %H:%M UTC")
    templates.env.filters["q"] = lambda s: quote(str(s), safe="")
    templates.env.filters["b64"] = lambda s: base64.b64encode(str(s).encode()).decode()
    return templates


def create_app(store: Store, config: WebConfig) -> Starlette:
    """The web view over `store` (read-only records) with `config`."""
    templates = _templates()
    throttle, slots, sessions = Throttle(), CheckSlots(PASSWORD_CHECKS_AT_ONCE), SessionStore()
    portal_sessions = SessionStore()  # customers' sessions: never looked up by the staff guard
    if not config.secure_cookie:
        log.warning(
            "web: the session cookie is not Secure (no --https-only, TLS or --proxy): "
            "it crosses the network in clear unless this server is reached on localhost only"
        )

    def signed_in(request: Request) -> StaffSession | None:
        sid = request.session.get("sid")
        return sessions.get(sid) if isinstance(sid, str) else None

    def page(request: Request, name: str, http_status: int = 200, **context: Any) -> Response:
        if "user" not in context:
            current = signed_in(request)
            context["user"] = current.username if current else None
        if "csrf" not in context:
            context["csrf"] = _csrf(request)
        return templates.TemplateResponse(request, name, context, status_code=http_status)

    def not_found(request: Request, what: str) -> Response:
        return page(request, "message.html", 404, title="Not found", message=what)

    def staff(endpoint: Callable[[Request], Response]) -> Callable[[Request], Response]:
        """Only for a signed-in, still active staff user; else to the login page."""

        def guarded(request: Request) -> Response:
            current = signed_in(request)
            account = store.user(current.username) if current else None
            if current is not None and (
                account is None
                or not account.active
                or password_stamp(account.password_hash) != current.stamp
            ):
                ended = sessions.revoke_user(current.username)  # gone, locked or new password
                log.info("web: %d session(s) of %s ended", ended, current.username)
                account = None
            if account is None:
                request.session.pop("sid", None)
                target = request.url.path + (f"?{request.url.query}" if request.url.query else "")
                return RedirectResponse(f"/login?next={quote(target, safe='')}", 303)
            return endpoint(request)

        return guarded

    def home(request: Request) -> Response:
        return RedirectResponse("/register", 303)

    def login(request: Request) -> Response:
        target = _local(request.query_params.get("next", "/register"))
        return page(request, "login.html", target=target, error=None)

    async def login_post(request: Request) -> Response:
        form = await request.form()
        username = str(form.get("username", "")).strip()[:100]
        password = str(form.get("password", ""))[:1000]
        target = _local(str(form.get("next", "/register")))
        if not secrets.compare_digest(str(form.get("csrf", "")), _csrf(request)):
            return page(request, "login.html", 400, target=target, error="Form expired: retry.")
        peer = request.client.host if request.client else None
        client = client_address(peer, request.headers.getlist("x-forwarded-for"), config.proxies)
        if not slots.take():  # no argon2 check free: answered without hashing
            log.warning("web: sign-in of %r from %s refused: checks busy", username, client)
            message = "The server is busy checking other sign-ins: retry in a few seconds."
            return refused(request, target, message, 1.0)
        try:
            verdict = throttle.attempt(username, client)  # counted before the check
            if not verdict.allowed:
                log.warning(
                    "web: sign-in of %r from %s refused: wait %.0f s",
                    username,
                    client,
                    verdict.wait_s,
                )
                wait = math.ceil(verdict.wait_s)
                message = f"Too many sign-in attempts: wait {wait} s and retry."
                return refused(request, target, message, verdict.wait_s)
            account = await run_in_threadpool(_check_password, store, username, password)
        finally:
            slots.give()
        if account is None:
            throttle.failed(username, client)
            log.info("web: failed sign-in of %r from %s", username, client)
            error = "Unknown user name or wrong password."
            return page(request, "login.html", 401, target=target, error=error)
        throttle.succeeded(username, client)
        old = request.session.get("sid")
        if isinstance(old, str):
            sessions.revoke(old)
        old_portal = request.session.get(PORTAL_SESSION_KEY)
        if isinstance(old_portal, str):
            portal_sessions.revoke(old_portal)
        request.session.clear()  # a new session: nothing carried over from before sign-in
        request.session["sid"] = sessions.open(
            account.username, account.display_name, account.password_hash
        )
        log.info("web: %s signed in from %s", account.username, client)
        return RedirectResponse(target, 303)

    def refused(
        request: Request, target: str, message: str, wait_s: float, login: str = "/login"
    ) -> Response:
        """429 with `message`, a link back to the sign-in and Retry-After (whole seconds): a
        fixed small page, no template (a hammering client costs the server next to nothing)."""
        back = html.escape(f"{login}?next={quote(target, safe='')}")
        body = (
            '<!doctype html><html lang="en"><meta charset="utf-8"><title>Sign in: wait</title>'
            f'<p id="error">{html.escape(message)}</p><p><a href="{back}">Sign in</a></p></html>'
        )
        headers = {"retry-after": str(max(1, math.ceil(wait_s)))}
        return HTMLResponse(body, 429, headers=headers)

    async def logout(request: Request) -> Response:
        form = await request.form()
        if secrets.compare_digest(str(form.get("csrf", "")), _csrf(request)):
            sid = request.session.get("sid")
            if isinstance(sid, str):
                sessions.revoke(sid)  # a copy of the cookie opens nothing any more
            request.session.clear()
        return RedirectResponse("/login", 303)

    def register(request: Request) -> Response:
        search = request.query_params.get("q", "")[:200]
        rows = store.register(search)
        return page(request, "register.html", rows=rows, search=search)

    def certificate(request: Request) -> Response:
        number = request.path_params["number"]
        row = store.certificate(number)
        if row is None:
            return not_found(request, f"No certificate {number} in the register.")
        checks, problem = [], None
        try:
            pdf = certificate_pdf(row.number, row.file, row.sha256)
            checks = verify_certificate(row.number, pdf, row.run_folder, config.trust)
        except DocumentError as exc:
            problem = str(exc)
        address, qr = _qr(request, config, row.number, row.manifest_sha256)
        try:  # the QR code page 1 carries, if any: spoken of only where one was printed
            printed = printed_verification_address(row.number, row.run_folder)
            qr_known = True
        except DocumentError:
            printed, qr_known = None, False
        return page(
            request,
            "certificate.html",
            row=row,
            checks=checks,
            verified=bool(checks) and all(c.ok for c in checks),
            unsigned=any(c.shown == "not signed" for c in checks),
            problem=problem,
            replaced_by=store.replaced_by(row.number),
            address=address,
            printed=printed,
            qr_known=qr_known,
            qr=qr_svg(printed) if printed else qr,
        )

    def certificate_file(request: Request) -> Response:
        number, kind = request.path_params["number"], request.path_params["kind"]
        if kind not in ("pdf", "xml"):
            return not_found(request, f"No document certificate.{kind}.")
        row = store.certificate(number)
        if row is None:
            return not_found(request, f"No certificate {number} in the register.")
        try:
            if kind == "pdf":
                data = certificate_pdf_bytes(row.number, row.file, row.sha256)
                media = "application/pdf"
            else:
                pdf = certificate_pdf(row.number, row.file, row.sha256)
                data = certificate_dcc(row.number, pdf, row.dcc_sha256)
                media = "application/xml"
        except DocumentError as exc:
            return not_found(request, str(exc))
        filename = "".join(c if c.isalnum() or c in "-_." else "_" for c in number)
        disposition = f'attachment; filename="{filename}.{kind}"'
        return Response(data, media_type=media, headers={"content-disposition": disposition})

    def due(request: Request) -> Response:
        try:
            days = int(request.query_params.get("days", DUE_DAYS_DEFAULT))
        except ValueError:
            days = -1
        if not 0 <= days <= DUE_DAYS_MAX:
            message = f"days: must be a whole number from 0 to {DUE_DAYS_MAX}"
            return page(request, "message.html", 400, title="Bad request", message=message)
        today = datetime.now(UTC).date()
        items = store.due(today=today, days=days)
        sensors = [i for i in items if i.kind == "sensor"]
        references = [i for i in items if i.kind == "reference"]
        return page(
            request, "due.html", days=days, today=today, sensors=sensors, references=references
        )

    def sensor(request: Request) -> Response:
        serial = request.path_params["serial"]
        try:
            history = store.history(serial)
        except RecordsError:
            return not_found(request, f"No sensor {serial} in the records.")
        return page(
            request,
            "sensor.html",
            history=history,
            chart=history_svg(history),
            rows=store.sensor_certificates(serial),
            shared=store.shared_runs(serial),
        )

    def verify(request: Request) -> Response:
        number = request.path_params["number"][:100]
        public: dict[str, Any] = {"public": True, "user": None, "csrf": ""}  # no session
        status = store.public_status(number, request.query_params.get("code", "")[:64])
        if status is None:
            return page(request, "verify.html", 404, number=number, status=None, **public)
        return page(request, "verify.html", number=number, status=status, **public)

    portal = PortalDeps(
        store=store,
        page=page,
        csrf=_csrf,
        slots=slots,
        proxies=config.proxies,
        refused=refused,
        sessions=portal_sessions,
        throttle=Throttle(),
        lab_host=urlsplit(config.verify_url).hostname if config.verify_url else None,
    )
    routes = [
        *portal_routes(portal),
        Route("/", home),
        Route("/login", login, methods=["GET"]),
        Route("/login", login_post, methods=["POST"]),
        Route("/logout", logout, methods=["POST"]),
        Route("/register", staff(register)),
        Route("/due", staff(due)),
        Route("/certificates/{number:path}/certificate.{kind:str}", staff(certificate_file)),
        Route("/certificates/{number:path}", staff(certificate)),
        Route("/sensors/{serial:path}", staff(sensor)),
        Route("/verify/{number:path}", verify, name="verify"),
    ]
    middleware = [
        Middleware(SecurityHeaders),
        Middleware(
            SessionMiddleware,
            secret_key=config.secret_key,
            session_cookie="accelcal_session",
            max_age=SESSION_MAX_AGE_S,
            same_site="lax",
            https_only=config.secure_cookie,
        ),
    ]
    app = Starlette(routes=routes, middleware=middleware)
    return app


def _check_password(store: Store, username: str, password: str) -> StaffUser | None:
    """The active staff user `username` when `password` is theirs, else None (argon2: run it
    off the event loop)."""
    return signed_in(store.user(username) if username else None, password)


def _csrf(request: Request) -> str:
    """The session's form token (made on first use)."""
    token = request.session.get("csrf")
    if not isinstance(token, str):
        token = secrets.token_urlsafe(24)
        request.session["csrf"] = token
    return token


def _local(target: str) -> str:
    """`target` when it is a path on this site, else the register (no open redirect)."""
    if target.startswith("/") and not target.startswith("//") and "\\" not in target:
        return target
    return "/register"


def _qr(request: Request, config: WebConfig, number: str, manifest: str) -> tuple[str, str]:
    """The public verification address of a certificate and its QR code (SVG)."""
    base = config.verify_url or str(request.base_url).rstrip("/") + "/verify"
    try:
        address = verify_address(base, number, manifest)
    except QrError as exc:
        return str(exc), ""
    return address, qr_svg(address)
