"""`accelcal register review NUMBER --confirm|--amended-by NEW --reason TEXT` and `accelcal
register reviews`: closing the reviews `accelcal impact` opens (ISO/IEC 17025 7.10) and listing
the open ones. Thin: the rules (an amendment of the same sensor replacing NUMBER; a confirmed
certificate still in force) are the records' (app.records.db.reviews)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from app.cli.listing import print_rows, review_row

if TYPE_CHECKING:
    from app.records.db.lab import Lab


def add_review_commands(
    gsub: Any,
    db_option: Callable[[argparse.ArgumentParser], None],
    list_options: Callable[[argparse.ArgumentParser], None],
) -> None:
    """Add `review` and `reviews` to the register's subcommands (`reviews` a list command:
    `list_options` gives it --db and --json)."""
    gr = gsub.add_parser("review", help="close a certificate's review: confirmed or amended")
    gr.add_argument("number", help="the certificate under review")
    how = gr.add_mutually_exclusive_group(required=True)
    how.add_argument("--confirm", action="store_true", help="the result stands as issued")
    how.add_argument(
        "--amended-by",
        metavar="NEW_NUMBER",
        help="the issued amendment (same sensor) that replaces NUMBER",
    )
    gr.add_argument("--reason", required=True, help="why (kept in the register and audited)")
    db_option(gr)
    list_options(gsub.add_parser("reviews", help="the certificates under review (open reviews)"))


def cmd_review(lab: Lab, args: argparse.Namespace) -> int:
    """Close NUMBER's open reviews as confirmed or amended; one line per review closed."""
    outcome = "confirmed" if args.confirm else "amended"
    closed = lab.close_review(
        args.number, outcome=outcome, reason=args.reason, amended_by=args.amended_by
    )
    for review in closed:
        how = f"amended by {review.amended_by}" if review.amended_by else "confirmed"
        print(f"{review.number}\treview closed: {how}\t({review.subject}; by {review.closed_by})")
    return 0


def cmd_reviews(lab: Lab, args: argparse.Namespace) -> int:
    """The open reviews, oldest first, and their count."""
    reviews = lab.reviews(open_only=True)
    if args.json:
        print_rows(review_row(r) for r in reviews)
        return 0
    for review in reviews:
        print(f"{review.number}\t{review.opened_utc:%Y-%m-%d}\t{review.subject}\t{review.reason}")
    print(f"{len(reviews)} certificate review{'' if len(reviews) == 1 else 's'} open")
    return 0


REVIEW_ACTIONS: dict[str, Callable[[Lab, argparse.Namespace], int]] = {
    "review": cmd_review,
    "reviews": cmd_reviews,
}
