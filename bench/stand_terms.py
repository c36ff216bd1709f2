"""The stand's own frequency-growing terms above 2 kHz as a laboratory evaluates them (type B
by Monte Carlo, JCGM 101), and the CMC they give: the blocks of sim/stand-fixture4-physics.toml
between its "stand_terms.py" markers.

Above 2 kHz a small exciter's terms stop following one power law: the armature's rocking mode
(5 kHz) swings the transverse term's phase, plate bending grows as f^2, the reference's mounted
resonance and the anti-alias corners' mismatch grow fast. The laboratory states each as a table
per third-octave band (dsp.budget_table): the root mean square over 20 000 realisations
(seed LAB_SEED) of sim/true_stand.py's model of that term, rounded up to two digits
(`sim.true_stand.characterised_terms`). Below 2.24 kHz the stand file's own components hold
(unchanged). The CMC above 4.47 kHz is the piezo's type B expanded uncertainty (k = 2) per band,
rounded down to two digits: the U the stand states for its best device, as the file's lower
band is.

Run: python bench/stand_terms.py [--check FILE | --write FILE | --smoke]
(prints the blocks; --check: exit 1 unless FILE holds them as printed; --write: puts them
between FILE's markers; --smoke: 500 draws, printed only, figures not meaningful)
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dsp.uncertainty import Budget, Quantity  # noqa: E402
from sim.true_stand import LAB_SEED, Term, characterised_terms  # noqa: E402

LINES_HZ = (2500.0, 3150.0, 4000.0, 5000.0, 6300.0, 8000.0, 10000.0, 12500.0, 16000.0, 20000.0)
FROM_HZ = 2236.1  # just above the edge between the 2 and 2.5 kHz bands (the file's own below)
CMC_FROM_HZ = 5000.0  # the file's lower CMC band ends here
CMC_TO_HZ = 40000.0
DRAWS = 20_000
# (term, quantity, Annex A kind, name): what each table states
TABLES = (
    (
        Term.MOUNTING,
        "magnitude",
        "mounting",
        "relative motion of DUT and reference (plate bending)",
    ),
    (Term.TRANSVERSE, "magnitude", "transverse_motion", "transverse motion (rocking mode)"),
    (Term.TRANSVERSE, "phase", "transverse_motion", "transverse motion (rocking mode), phase"),
    (
        Term.REFERENCE_RESONANCE,
        "magnitude",
        "reference_frequency_dependence",
        "reference frequency response (mounted resonance)",
    ),
    (Term.ANTIALIAS, "phase", "channel_phase_match", "anti-alias filters' corner mismatch, phase"),
    (Term.ANTIALIAS, "magnitude", "other", "anti-alias filters' corner mismatch"),
)
BEGIN, END = "# --- stand_terms.py: begin", "# --- stand_terms.py: end"


def _up(x: float) -> float:
    """`x` rounded up to two significant digits."""
    if x <= 0:
        return 0.0
    scale = 10.0 ** (math.floor(math.log10(x)) - 1)
    return math.ceil(x / scale - 1e-9) * scale


def _down(x: float) -> float:
    """`x` rounded down to two significant digits."""
    scale = 10.0 ** (math.floor(math.log10(x)) - 1)
    return math.floor(x / scale + 1e-9) * scale


def _g(x: float) -> str:
    return f"{float(f'{x:.2g}'):g}" if x else "0.0"


def component_block(draws: int = DRAWS) -> tuple[str, list[dict[str, object]]]:
    """The [[component]] tables (TOML) and the entries they are."""
    f = np.array(LINES_HZ)
    terms = characterised_terms(f, tuple(dict.fromkeys(t for t, *_ in TABLES)), draws=draws)
    entries, text = [], [f"{BEGIN} (the stand's terms above 2 kHz; do not edit by hand)"]
    for term, quantity, kind, name in TABLES:
        magnitude, phase = terms[term]
        values = phase if quantity == "phase" else magnitude
        rows = [[float(fi), _up(float(v))] for fi, v in zip(LINES_HZ, values, strict=True)]
        entry = {
            "name": name,
            "kind": kind,
            "distribution": "standard",
            "quantity": quantity,
            "min_frequency_hz": FROM_HZ,
            "table": rows,
        }
        entries.append(entry)
        unit = "degrees" if quantity == "phase" else "fraction"
        text += [
            "[[component]]",
            f'name = "{name}"',
            f'kind = "{kind}"',
            'distribution = "standard"',
            f'quantity = "{quantity}"',
            f"min_frequency_hz = {FROM_HZ}",
            f"# Hz, standard uncertainty ({unit}): rms of {draws} draws, seed {LAB_SEED}",
            "table = [" + ", ".join(f"[{fi:g}.0, {_g(v)}]" for fi, v in rows) + "]",
            f'note = "{term.value}: sim/true_stand.py characterised (bench/stand_terms.py)"',
            "",
        ]
    return "\n".join(text), entries


def cmc_block(budget: Budget) -> str:
    """The [[cmc]] bands from CMC_FROM_HZ: the type B U (k = 2) at each line, rounded down."""
    lines = [x for x in LINES_HZ if x >= CMC_FROM_HZ]
    edges = [CMC_FROM_HZ, *(math.sqrt(a * b) for a, b in itertools.pairwise(lines)), CMC_TO_HZ]
    out = []
    for i, f in enumerate(lines):
        u = {
            q: math.sqrt(sum(c.standard_uncertainty_at(f) ** 2 for c in budget.at(f, q)))
            for q in (Quantity.MAGNITUDE, Quantity.PHASE)
        }
        out += [
            "[[cmc]]",
            f"min_frequency_hz = {edges[i]:.1f}",
            f"max_frequency_hz = {edges[i + 1]:.1f}",
            f"magnitude_percent = {_g(_down(200.0 * u[Quantity.MAGNITUDE]))}",
            f"phase_deg = {_g(_down(2.0 * u[Quantity.PHASE]))}",
            "",
        ]
    return "\n".join(out)


def blocks(stand: Path, draws: int = DRAWS) -> str:
    """Both blocks as the stand file holds them (the CMC from its budget with the tables)."""
    from app.stand import config as stand_config

    text, entries = component_block(draws)
    names = tuple(name for *_, name in TABLES)
    own = [c for c in stand_config.load(stand).budget.components if not c.name.startswith(names)]
    budget = Budget((*own, *Budget.from_list(entries).components))
    return f"{text}\n{cmc_block(budget)}{END}\n"


def held(stand: Path) -> str:
    """What `stand` holds between the markers (empty without them)."""
    content = stand.read_text(encoding="utf-8")
    if BEGIN not in content or END not in content:
        return ""
    return content[content.index(BEGIN) : content.index(END) + len(END)] + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", type=Path, help="a stand file that must hold the blocks")
    parser.add_argument("--write", type=Path, help="put the blocks between FILE's markers")
    parser.add_argument("--stand", type=Path, default=ROOT / "sim" / "stand-fixture4-physics.toml")
    parser.add_argument("--smoke", action="store_true", help="500 draws, print only")
    args = parser.parse_args()
    stand = args.check or args.write or args.stand
    if args.smoke:  # the code path, not the figures
        print(blocks(stand, draws=500), end="")
        return 0
    expected = blocks(stand)
    print(expected, end="")
    if args.write is not None:
        old = held(args.write)
        if not old:
            print(f"{args.write}: no {BEGIN!r} ... {END!r} markers", file=sys.stderr)
            return 2
        content = args.write.read_text(encoding="utf-8")
        args.write.write_text(content.replace(old, expected), encoding="utf-8")
    if args.check is not None and held(args.check) != expected:
        print(f"{args.check}: does not hold these blocks as printed", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
