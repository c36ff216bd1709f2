"""Keeping: the run record, the run folder and its manifest, the register, the records database."""
