"""The certificate dialog's issue-35 fields (app.gui.certificate_dialog): the address not
stated with its reason, the relative humidity (refused at its field when it is not one), the
specification (kind and document together, else refused at the field) and the offered
mounting, each carried into the CertificateInfo the service issues."""

from __future__ import annotations

from typing import Any

import pytest
from PySide6.QtWidgets import QDialog

from app.certificate.info import Specification, SpecKind
from app.gui.certificate_dialog import CertificateDialog
from app.records.run_record import RunRecord


def _record() -> Any:
    return RunRecord(run_id="R-1", status="complete", abort_reason=None, final_output_v=0.0)


@pytest.fixture()
def dialog(qtbot) -> CertificateDialog:
    made = CertificateDialog(
        None,
        _record(),
        {"mounting": "stud M5"},
        offered_from="template low level of model PCB 352C33",
        template="low level",
    )
    qtbot.addWidget(made)
    return made


def test_the_offered_mounting_says_where_it_comes_from(dialog: CertificateDialog) -> None:
    edit = dialog.edits["mounting"]
    assert edit.text() == "stud M5"
    assert edit.toolTip() == "from template low level of model PCB 352C33"
    info = dialog.info()
    assert info.mounting == "stud M5" and info.template == "low level"


def test_humidity_address_reason_and_specification_reach_the_info(
    dialog: CertificateDialog,
) -> None:
    dialog.humidity.setText("45,5 %")
    dialog.edits["address_not_stated"].setText("walk-in customer")
    dialog.spec_kind.setCurrentIndex(dialog.spec_kind.findData(SpecKind.DATASHEET))
    dialog.edits["spec_id"].setText("PCB 352C33 data sheet rev. D")
    dialog.accept()
    assert dialog.result() == QDialog.DialogCode.Accepted
    info = dialog.info()
    assert info.humidity_percent == 45.5 and info.address_not_stated == "walk-in customer"
    assert info.specification == Specification(
        SpecKind.DATASHEET, "PCB 352C33 data sheet rev. D", ""
    )


@pytest.mark.parametrize("typed", ["wet", "120 %", "-3"])
def test_a_humidity_that_is_not_one_keeps_the_dialog_open_saying_so(
    dialog: CertificateDialog, typed: str
) -> None:
    dialog.humidity.setText(typed)
    dialog.accept()
    assert dialog.result() != QDialog.DialogCode.Accepted
    assert "humidity" in dialog.marks.reason(dialog.humidity)


def test_a_specification_needs_its_kind_and_its_document(dialog: CertificateDialog) -> None:
    dialog.spec_kind.setCurrentIndex(dialog.spec_kind.findData(SpecKind.CUSTOMER))
    dialog.accept()
    assert dialog.result() != QDialog.DialogCode.Accepted
    assert "document and revision" in dialog.marks.reason(dialog.edits["spec_id"])
    dialog.spec_kind.setCurrentIndex(0)
    dialog.edits["spec_id"].setText("AS-12 rev. C")
    dialog.accept()
    assert "choose its kind" in dialog.marks.reason(dialog.edits["spec_id"])
    assert dialog.specification() is None
