"""`accelcal web` (the lab's read-only web view, the options of `python -m app.web`),
`accelcal records user list`, `accelcal records user add NAME` (a staff user of the web
view) and `accelcal records user passwd NAME` (a new password: the user's web sessions end);
`accelcal records account add|list|passwd|disable|enable|remove` for customers' accounts of
the portal (app.web.accounts), each bound to one customer. A password is read from a prompt
or, with --password-stdin, from standard input: never from the command line."""

from __future__ import annotations

import argparse
import getpass
import sys

from app.cli.exits import EXIT_OK, UsageError


def add_web_commands(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add `web` and `records user add|passwd|list` to the top-level subparsers."""
    from app.web.options import add_options

    w = sub.add_parser("web", help="the lab's read-only web view (register, verification)")
    add_options(w)
    r = sub.add_parser(
        "records", help="records administration: staff users, customers' portal accounts"
    )
    rsub = r.add_subparsers(dest="records_command", required=True, metavar="WHAT")
    u = rsub.add_parser("user", help="staff users of the web view")
    usub = u.add_subparsers(dest="user_action", required=True, metavar="ACTION")
    ua = usub.add_parser("add", help="add a staff user (password from a prompt or stdin)")
    ua.add_argument("name", help="user name (letters, digits, . _ -)")
    ua.add_argument("--display-name", help="name shown in the web view (default: NAME)")
    ua.add_argument(
        "--password-stdin", action="store_true", help="read the password from standard input"
    )
    ua.add_argument("--db", metavar="URL", help="records database (default $ACCELCAL_DB)")
    up = usub.add_parser("passwd", help="a new password for a staff user (ends their sessions)")
    up.add_argument("name", help="user name")
    up.add_argument(
        "--password-stdin", action="store_true", help="read the password from standard input"
    )
    up.add_argument("--db", metavar="URL", help="records database (default $ACCELCAL_DB)")
    ul = usub.add_parser("list", help="the staff users: name, display name, active, created")
    ul.add_argument(
        "--json",
        action="store_true",
        help="a JSON array of objects (stable keys, ISO 8601 dates, numbers as numbers)",
    )
    ul.add_argument("--db", metavar="URL", help="records database (default $ACCELCAL_DB)")
    _add_account_commands(rsub)


def _add_account_commands(rsub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """`records account ...`: customers' accounts of the web view's portal."""
    db_help = "records database (default $ACCELCAL_DB)"
    stdin_help = "read the password from standard input"
    a = rsub.add_parser("account", help="customers' accounts of the web portal (/portal)")
    asub = a.add_subparsers(dest="account_action", required=True, metavar="ACTION")
    aa = asub.add_parser("add", help="add a customer's account (password from a prompt or stdin)")
    aa.add_argument("name", help="user name (letters, digits, . _ -)")
    aa.add_argument("--customer", required=True, help="the records customer it sees (its name)")
    aa.add_argument("--display-name", help="name shown in the portal (default: NAME)")
    aa.add_argument("--password-stdin", action="store_true", help=stdin_help)
    aa.add_argument("--db", metavar="URL", help=db_help)
    ap = asub.add_parser("passwd", help="a new password (ends the account's sessions)")
    ap.add_argument("name", help="user name")
    ap.add_argument("--password-stdin", action="store_true", help=stdin_help)
    ap.add_argument("--db", metavar="URL", help=db_help)
    for action, what in (
        ("disable", "disable an account (its sessions end; it can no longer sign in)"),
        ("enable", "enable a disabled account again"),
        ("remove", "remove an account (the audit trail keeps that it existed)"),
    ):
        p = asub.add_parser(action, help=what)
        p.add_argument("name", help="user name")
        p.add_argument("--db", metavar="URL", help=db_help)
    al = asub.add_parser("list", help="the accounts: name, display name, customer, state, created")
    al.add_argument("--json", action="store_true", help="a JSON array of objects")
    al.add_argument("--db", metavar="URL", help=db_help)


def cmd_web(args: argparse.Namespace) -> int:
    from app.web.__main__ import serve

    return serve(args)


def _password(args: argparse.Namespace) -> str:
    """The (new) password: one line of stdin with --password-stdin, else typed twice."""
    if args.password_stdin:
        line = sys.stdin.readline()
        return line[:-1] if line.endswith("\n") else line
    if not sys.stdin.isatty():
        raise UsageError("password: no terminal to prompt on; use --password-stdin")
    first = getpass.getpass("password: ")
    if getpass.getpass("password again: ") != first:
        raise UsageError("password: the two entries differ")
    return first


def cmd_records(args: argparse.Namespace) -> int:
    from app.records.db.engine import open_engine

    if args.records_command == "account":
        return _account(args)
    if args.user_action == "list":
        return _list_users(args)
    if args.user_action == "passwd":
        from app.web.users import set_password

        set_password(open_engine(args.db), args.name, _password(args))
        print(f"password of {args.name.strip()} changed: their web sessions end")
        return EXIT_OK
    from app.web.users import add_user

    password = _password(args)
    add_user(
        open_engine(args.db),
        args.name,
        password,
        display_name=args.display_name or args.name,
    )
    print(f"user {args.name.strip()} added")
    return EXIT_OK


def _list_users(args: argparse.Namespace) -> int:
    """`accelcal records user list`: one line per staff user, or --json."""
    from app.cli.listing import print_rows, user_row
    from app.records.db.engine import open_engine
    from app.web.users import list_users

    users = list_users(open_engine(args.db))
    if args.json:
        print_rows(user_row(u) for u in users)
        return EXIT_OK
    for user in users:
        state = "active" if user.active else "locked"
        print(f"{user.username}\t{user.display_name}\t{state}\tsince {user.created_utc:%Y-%m-%d}")
    print(f"{len(users)} user{'' if len(users) == 1 else 's'}")
    return EXIT_OK


def _account(args: argparse.Namespace) -> int:
    """`accelcal records account ACTION`."""
    from app.records.db.engine import open_engine
    from app.web import accounts

    name = args.name.strip() if hasattr(args, "name") else ""
    if args.account_action == "list":
        rows = accounts.list_accounts(open_engine(args.db))
        if args.json:
            from app.cli.listing import account_row, print_rows

            print_rows(account_row(r) for r in rows)
            return EXIT_OK
        for row in rows:
            state = "active" if row.active else "disabled"
            print(
                f"{row.username}\t{row.display_name}\t{row.customer}\t{state}"
                f"\tsince {row.created_utc:%Y-%m-%d}"
            )
        print(f"{len(rows)} account{'' if len(rows) == 1 else 's'}")
        return EXIT_OK
    if args.account_action == "add":
        password = _password(args)
        accounts.add_account(
            open_engine(args.db),
            args.name,
            password,
            customer=args.customer,
            display_name=args.display_name or args.name,
        )
        print(f"account {name} added for customer {args.customer.strip()}")
    elif args.account_action == "passwd":
        accounts.set_account_password(open_engine(args.db), args.name, _password(args))
        print(f"password of account {name} changed: its portal sessions end")
    elif args.account_action in ("disable", "enable"):
        active = args.account_action == "enable"
        accounts.set_account_active(open_engine(args.db), args.name, active)
        print(f"account {name} {args.account_action}d")
    else:
        accounts.remove_account(open_engine(args.db), args.name)
        print(f"account {name} removed")
    return EXIT_OK
