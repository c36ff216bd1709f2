"""Files attached to a PDF (the certificate's DCC, the validation report's record): PDF/A-3
style associated files, written in place."""

from __future__ import annotations

from pathlib import Path


def embed(pdf: Path, name: str, data: bytes) -> None:
    """Attach `data` to the PDF as an associated file (PDF/A-3 style: /AF in the catalogue,
    /AFRelationship /Data on the file specification), in place."""
    from pypdf import PdfWriter
    from pypdf.generic import ArrayObject, NameObject

    writer = PdfWriter(clone_from=str(pdf))
    writer.add_attachment(name, data)
    names = writer.root_object["/Names"]["/EmbeddedFiles"]["/Names"]  # type: ignore[index]
    spec = names[-1].get_object()
    spec[NameObject("/AFRelationship")] = NameObject("/Data")
    writer.root_object[NameObject("/AF")] = ArrayObject([names[-1]])
    with pdf.open("wb") as handle:
        writer.write(handle)
