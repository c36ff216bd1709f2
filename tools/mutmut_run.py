"""mutmut 2.5.1 with one fix: update_mutant_status sometimes finds no cached line for a
mutant ("Attribute Mutant.line is required") and aborts the whole run; look the line up by its
number instead, and report (not crash) if that fails too."""

import sys

import mutmut.cache as cache
from mutmut.__main__ import climain
from pony.orm import db_session


@cache.init_db
@db_session
def update_mutant_status(file_to_mutate, mutation_id, status, tests_hash):
    sourcefile = cache.SourceFile.get(filename=file_to_mutate)
    line = cache.Line.get(
        sourcefile=sourcefile, line=mutation_id.line, line_number=mutation_id.line_number
    )
    if line is None:
        candidates = cache.Line.select(
            lambda x: x.sourcefile == sourcefile and x.line_number == mutation_id.line_number
        )[:]
        line = candidates[0] if len(candidates) == 1 else None
        print(f"\n[mutmut_run] line lookup fallback for {mutation_id}: {line}", file=sys.stderr)
    if line is None:
        return
    mutant = cache.Mutant.get(line=line, index=mutation_id.index)
    if mutant is None:
        print(f"\n[mutmut_run] no mutant for {mutation_id}", file=sys.stderr)
        return
    mutant.status = status
    mutant.tested_against_hash = tests_hash


cache.update_mutant_status = update_mutant_status

if __name__ == "__main__":
    sys.exit(climain())
