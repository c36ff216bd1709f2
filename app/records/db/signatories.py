"""Signatory names as the register takes and compares them (issue 24 point 5).

A name is NFKC-normalised, stripped of zero-width and other format characters (Unicode
category Cf), its runs of white space made one space; two names are the same person when these
forms are equal without regard to case. A name whose letters mix scripts (a Cyrillic or Greek
letter in an otherwise Latin name), or a Cyrillic/Greek name made only of letters that look
Latin, is refused by field: it would let one person pass the two-person rule as two.
"""

from __future__ import annotations

import unicodedata

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
