"""Issue 32 point 1, first acceptance point, on the path users take (`accelcal run --stand`,
then `accelcal certificate`): a budget complete by tag but implausibly small gets no PASS and
no certificate, or states U no smaller than the laboratory's CMC; a stand without a CMC states
no PASS and gets no certificate."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.cli import main
from dsp.annex_a import PLAUSIBLE_MINIMUM, ComponentKind

ROOT = Path(__file__).resolve().parents[3]
SIM_STAND = (ROOT / "sim" / "stand.toml").read_text(encoding="utf-8")
ITEMS = ["--customer", "ACME Ltd",
         "--customer-address", "1 Test Street, 00-001 Testtown",
         "--authorised-by", "J. Smith", "--temperature", "23",
         "--mounting", "stud"]  # fmt: skip


def _stand(tmp_path: Path, value_of=None, *, cmc: bool = True, skew_s: float = 1e-7) -> Path:
    """The built-in simulated stand with each [[component]]'s value replaced by
    value_of(kind, normal) when given (same names, so [simulation] still applies), without its
    [[cmc]] bands when `cmc` is False."""
    head, *blocks = SIM_STAND.split("[[component]]")
    out = []
    for block in blocks:
        if value_of is None:
            out.append(block)
            continue
        kind = ComponentKind(re.search(r'^kind = "(\w+)"', block, re.M).group(1))
        normal = 'distribution = "normal"' in block
        block = re.sub(r"^value = .*$", f"value = {value_of(kind, normal)!r}", block, flags=re.M)
        out.append(block)
    text = "[[component]]".join([head, *out])
    text = text.replace("skew_tolerance_s = 1e-7", f"skew_tolerance_s = {skew_s!r}")
    if not cmc:
        text = re.sub(r"\[\[cmc\]\]\n(?:[a-z_]+ = [\d.]+\n)+", "", text)
        assert "[[cmc]]" not in text
    path = tmp_path / "stand.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _run(tmp_path: Path, stand: Path, capsys) -> tuple[int, Path | None, str]:
    out = tmp_path / "runs"
    argv = ["run", "--stand", str(stand), "--dut", "piezo", "--dut-id", "SN-C"]
    code = main([*argv, "--periods", "3", "--tolerance", "5", "--technician", "A. T",
                 "--out", str(out)])  # fmt: skip
    text = "\n".join(capsys.readouterr())
    folders = list(out.iterdir()) if out.exists() else []
    return code, (folders[0] if folders else None), text


def test_a_budget_complete_by_tag_with_nominal_values_is_refused_by_name(tmp_path, capsys):
    """The issue's gamed budget: every component 1e-9, each Annex A kind tagged: `run` exits 2
    naming the components before anything is played; no run folder, so no certificate."""
    stand = _stand(tmp_path, lambda kind, normal: 1e-9, skew_s=1e-18)
    code, folder, text = _run(tmp_path, stand, capsys)
    assert code == 2 and folder is None
    assert "Traceback" not in text
    assert "'reference standard calibration' (reference_calibration): standard uncertainty" in text
    assert "below the plausible minimum 0.0005 for its kind" in text
    assert "'channel skew (sampling delay) tolerance' (skew)" in text


def _just_plausible(kind: ComponentKind, normal: bool) -> float:
    """A value whose standard uncertainty is 1.2 times its kind's plausible minimum."""
    return 1.2 * PLAUSIBLE_MINIMUM[kind] * (2.0 if normal else 3**0.5)


@pytest.mark.integration
def test_a_plausible_but_tiny_budget_states_the_cmc_and_the_certificate_says_so(tmp_path, capsys):
    """Complete and plausible by kind, yet its U (about 0.15 %) is far below the CMC: every
    stated U is the CMC's, the run and the certificate say where. One short simulated run
    (about 8 s) and one certificate: the path users take."""
    stand = _stand(tmp_path, _just_plausible)
    code, folder, text = _run(tmp_path, stand, capsys)
    assert code == 0 and folder is not None, text
    results = json.loads((folder / "results.json").read_text())["results"]
    bands = results["cmc"]
    assert [b["magnitude_percent"] for b in bands] == [0.7, 2.0]

    def cmc_at(f: float) -> tuple[float, float]:
        hits = [b for b in bands if b["min_frequency_hz"] <= f <= b["max_frequency_hz"]]
        return max(b["magnitude_percent"] for b in hits), max(b["phase_deg"] for b in hits)

    for ln in results["lines"]:
        mag, phase = cmc_at(ln["nominal_frequency_hz"])
        assert 100 * ln["relative_expanded_uncertainty"] == pytest.approx(mag)  # bounded
        assert ln["phase_expanded_uncertainty_deg"] == pytest.approx(phase)
        assert "U" in ln["cmc_bounds"] and "phase U" in ln["cmc_bounds"]
        if ln["deviation_percent"] != 0.0:
            least = mag * (1 + ln["deviation_percent"] / 100)
            assert ln["deviation_expanded_percent"] == pytest.approx(least)
    assert results["verdict"] == "PASS"
    assert (
        "it sets the stated value of U, phase U, U of the deviation at 10 to 125 Hz; "
        "U, phase U at 160 Hz; U, phase U, U of the deviation at 200 to 2500 Hz." in text
    )

    assert main(["certificate", str(folder), *ITEMS]) == 0, capsys.readouterr().err
    pdf = " ".join(p.extract_text() for p in PdfReader(folder / "certificate.pdf").pages)
    pdf = " ".join(pdf.split())
    assert "No stated uncertainty is smaller than the laboratory's calibration and" in pdf
    assert "U, phase U at 160 Hz" in pdf
    assert "U dev." in pdf  # the characteristic's U, per line, as the DCC states it
    dcc = (folder / "certificate.xml").read_text(encoding="utf-8")
    assert "Calibration and measurement capability" in dcc and "U, phase U at 160 Hz" in dcc


@pytest.mark.integration
def test_a_stand_without_a_cmc_states_no_pass_and_gets_no_certificate(tmp_path, capsys):
    """The shipped budget without [[cmc]]: the run completes, its verdict is not PASS and says
    why; `certificate` refuses it (exit 2). One short simulated run (about 8 s)."""
    code, folder, text = _run(tmp_path, _stand(tmp_path, cmc=False), capsys)
    assert code == 0 and folder is not None, text  # complete: results for review
    results = json.loads((folder / "results.json").read_text())["results"]
    assert results["verdict"] != "PASS" and results["cmc"] == []
    assert any(r.startswith("blocks PASS (no CMC): no CMC") for r in results["verdict_reasons"])
    assert "warning: no CMC: results for review only" in text
    assert main(["certificate", str(folder), *ITEMS]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "no certificate" in err and "CMC" in err
    assert not list(folder.glob("certificate*"))
