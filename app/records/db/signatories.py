"""Signatory names as the register takes and compares them (issue 24 point 5).

A name is NFKC-normalised, stripped of zero-width and other format characters (Unicode
category Cf), its runs of white space made one space; two names are the same person when these
forms are equal without regard to case. A name whose letters mix scripts (a Cyrillic or Greek
letter in an otherwise Latin name), or a Cyrillic/Greek name made only of letters that look
Latin, is refused by field: it would let one person pass the two-person rule as two.

Under the lab's two-person rule a signatory is a person, not a string (issue 33 point 3): each
name is resolved to one active user of the records (`find_person`: by user name or the name
recorded for them), and the rule compares the users (`check_two_persons`: their ids, and their
recorded names), so case, spacing, format characters, look-alike letters or a ", function"
suffix cannot make one person two. The function ("head of laboratory") is its own item.
"""

from __future__ import annotations

import unicodedata
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.records.db.models import User
from app.records.db.store import RecordsError, text_field

# Cyrillic and Greek letters that print like Latin ones (Unicode confusables, the common set)
_LOOK_LATIN = set("АВЕЗІЈКМНОРЅСТУХавеіјорѕсухӏԁԛԝΑΒΕΖΗΙΚΜΝΟΡΤΥΧαιικνορτυχϲ")


def _script(ch: str) -> str:
    """The script of a letter by its Unicode name's first word (LATIN, CYRILLIC, GREEK, ...)."""
    try:
        return unicodedata.name(ch).split(" ", 1)[0]
    except ValueError:
        return "UNKNOWN"


def signatory_name(value: str | None, field: str) -> str:
    """The name as stored: NFKC, format characters removed, spaces collapsed; RecordsError
    naming `field` when blank, too long or written in confusable scripts."""
    text = unicodedata.normalize("NFKC", value or "")
    text = "".join(ch for ch in text if unicodedata.category(ch) != "Cf")
    text = text_field(" ".join(text.split()), field)
    letters = [ch for ch in text if ch.isalpha()]
    scripts = sorted({_script(ch) for ch in letters})
    if len(scripts) > 1:
        raise RecordsError(
            f"{field}: {text!r} mixes scripts ({', '.join(s.title() for s in scripts)}); a "
            "look-alike letter makes another name, type it in one script"
        )
    if scripts and scripts[0] in ("CYRILLIC", "GREEK") and all(c in _LOOK_LATIN for c in letters):
        raise RecordsError(
            f"{field}: {text!r} is written in {scripts[0].title()} letters that look Latin; "
            "type the name in Latin letters"
        )
    return text


def same_person(a: str, b: str) -> bool:
    """Whether two names (as `signatory_name` gives them) name one person: equal without regard
    to case (full Unicode case folding) or spacing."""
    return "".join(a.casefold().split()) == "".join(b.casefold().split())


# ---- signatories as persons (issue 33 point 3) -------------------------------------------------


@dataclass(frozen=True)
class Person:
    """A signatory resolved to a user of the records (the users table): their id, user name and
    the name recorded for them (as `signatory_name` gives it), which the certificate prints."""

    id: int
    username: str
    name: str


def _compact(name: str) -> str:
    return "".join(name.casefold().split())


def _before_comma(name: str) -> str:
    return _compact(name.split(",", 1)[0])


def find_person(session: Session, text: str, field: str) -> Person:
    """The active user `text` names: by user name (without regard to case) or by the name
    recorded for them (`same_person`); RecordsError naming `field` when it names nobody, more
    than one user, or a locked user. A name followed by a function ("A. Tech, head of
    laboratory") names nobody: the refusal says which person and option were meant."""
    name = signatory_name(text, field)
    users = list(session.scalars(select(User).order_by(User.id)).all())
    found = {
        u.id: u
        for u in users
        if u.username.casefold() == name.casefold() or same_person(u.display_name, name)
    }
    if not found:
        meant = [
            u for u in users if "," in name and _compact(u.display_name) == _before_comma(name)
        ]
        hint = (
            f"; {meant[0].display_name!r} is user {meant[0].username}: give the name alone and "
            f"the function with its own option (--authorised-function)"
            if meant
            else " (accelcal records user list); name the person by user name or recorded name"
        )
        raise RecordsError(
            f"{field}: {name!r} is no person on record: the lab's two-person rule takes "
            f"signatories who are users of the records{hint}"
        )
    if len(found) > 1:
        names = ", ".join(sorted(u.username for u in found.values()))
        raise RecordsError(
            f"{field}: {name!r} names more than one user ({names}): give the user name"
        )
    (user,) = found.values()
    if not user.active:
        raise RecordsError(f"{field}: user {user.username} is locked and may not sign")
    recorded = signatory_name(user.display_name, f"{field}: user {user.username}'s recorded name")
    return Person(user.id, user.username, recorded)


def check_two_persons(prepared: Person, approved: Person) -> None:
    """RecordsError (field "approved by") unless the two signatories are two persons: two
    users, whose recorded names are not one name either (equal but for case and spacing, or
    one the other with a ", function" after it)."""
    if prepared.id == approved.id:
        raise RecordsError(
            "approved by: the lab's two-person rule needs another person: "
            f"{approved.name!r} is user {approved.username}, who prepared it"
        )
    a, b = prepared.name, approved.name
    if same_person(a, b) or _compact(a) == _before_comma(b) or _before_comma(a) == _compact(b):
        raise RecordsError(
            "approved by: the lab's two-person rule needs another person: users "
            f"{prepared.username} ({a!r}) and {approved.username} ({b!r}) are recorded under "
            "one person's name (ask the administrator to correct the users)"
        )
