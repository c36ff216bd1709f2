"""Signatories as persons (app.records.db.signatories; issue 33 point 3): under the lab's
two-person rule prepared by and approved by are resolved to users of the records and the rule
compares the users, on SQLite and PostgreSQL. The issue's attack (prepared by "A. Tech",
approved by "A. Tech, head of laboratory") and its variants run again, each refused naming what
was found."""

from __future__ import annotations

import re

import pytest
from sqlalchemy import Engine, update
from sqlalchemy.orm import Session

from app.records.db.lab import Lab, RecordsError
from app.records.db.models import User
from tests.records_db import add_staff


@pytest.fixture
def lab(engine: Engine) -> Lab:
    """The records with three persons on record and the two-person rule on."""
    add_staff(engine, ("atech", "A. Tech"), ("jsmith", "J. Smith"), ("qm", "Quality Manager"))
    lab = Lab(engine, actor="t")
    lab.set_setting("two_person_rule", "on")
    return lab


SAME = "approved by: the lab's two-person rule needs another person: 'A. Tech' is user atech"


ATTACKS = [
    # the case: the name with the function after it is no person
    (
        "A. Tech, head of laboratory",
        "approved by: 'A. Tech, head of laboratory' is no person on record: the lab's "
        "two-person rule takes signatories who are users of the records; 'A. Tech' is user "
        "atech: give the name alone and the function with its own option "
        "(--authorised-function)",
    ),
    ("A. Tech,head of laboratory", "is no person on record"),
    ("A. Tech (head of laboratory)", "is no person on record"),
    ("A. Tech - head of laboratory", "is no person on record"),
    # the same person however written: one user, refused by the rule
    ("a. tech", SAME),
    ("A.  TECH ", SAME),
    ("A.\u00a0Tech", SAME),  # no-break space
    ("A. Te\u200bch", SAME),  # zero-width space
    ("\uff21. Tech", SAME),  # fullwidth A (NFKC)
    ("ATECH", SAME),  # the user name, any case
    # look-alike letters: refused before any lookup
    ("\u0410. Tech", "approved by: 'А. Tech' mixes scripts (Cyrillic, Latin)"),
    ("\u0410. \u0422\u0435\u0441\u04bb", "'А. Тесһ' is no person on record"),  # all Cyrillic
    # nobody of that name
    ("B. Tech", "approved by: 'B. Tech' is no person on record"),
]


def test_the_suffix_signatory_and_its_variants_are_refused(lab: Lab) -> None:
    """Prepared by "A. Tech"; each approver of ATTACKS refused, naming what was found."""
    for approved, found in ATTACKS:
        with pytest.raises(RecordsError, match=re.escape(found)) as refused:
            lab.check_signatories("A. Tech", approved)
        assert str(refused.value).startswith("approved by: "), approved


def test_two_persons_pass_and_the_names_recorded_for_them_are_kept(lab: Lab) -> None:
    assert lab.check_signatories("atech", "QM") == ("A. Tech", "Quality Manager")
    assert lab.check_signatories(" a. tech ", "j.  smith") == ("A. Tech", "J. Smith")


def test_two_accounts_under_one_persons_name_are_one_person(lab: Lab, engine: Engine) -> None:
    """An administrator's slip (or trick): a second account recorded under the same name, or
    the name with a function after it, does not make a second person."""
    add_staff(engine, ("atech2", "a. TECH"), ("head", "A. Tech, head of laboratory"))
    with pytest.raises(RecordsError, match=r"names more than one user \(atech, atech2\)"):
        lab.check_signatories("qm", "A. Tech")
    for other in ("atech2", "head"):
        with pytest.raises(RecordsError, match="recorded under one person's name"):
            lab.check_signatories("atech", other)
        with pytest.raises(RecordsError, match="recorded under one person's name"):
            lab.check_signatories(other, "atech")


def test_a_locked_user_may_not_sign(lab: Lab, engine: Engine) -> None:
    with Session(engine) as s, s.begin():
        s.execute(update(User).where(User.username == "qm").values(active=False))
    with pytest.raises(RecordsError, match=r"^approved by: user qm is locked"):
        lab.check_signatories("atech", "qm")


def test_a_user_name_and_another_users_recorded_name_are_ambiguous(
    lab: Lab, engine: Engine
) -> None:
    """ "qm" is a user name and another user's recorded name: it names nobody for sure."""
    add_staff(engine, ("quality", "qm"))
    with pytest.raises(RecordsError, match=r"names more than one user \(qm, quality\)"):
        lab.check_signatories("atech", "qm")


def test_without_the_rule_names_are_text(engine: Engine) -> None:
    """The rule off (the default): nobody is resolved, the names are kept as typed (the
    certificate's note says the rule is off)."""
    lab = Lab(engine, actor="t")
    assert lab.check_signatories("A. Tech", "A. Tech, head of laboratory") == (
        "A. Tech",
        "A. Tech, head of laboratory",
    )
