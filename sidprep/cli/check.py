"""``sidprep check FILE``: re-run the model checks of a SID file; exit 1 when one fails."""

from __future__ import annotations

from sidprep.cli.options import add_quiet


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "check", help="re-run the model checks of a SID file (.sid.h5 or .SID_FEM); exit 1 on failure",
        description="Checks physical possibility (mass, inertia about the CM, Me, Ke, node orientations), "
                    "the self-consistency identities of docs/sid-spec.md 4.8 (also entry by entry, which finds "
                    "deleted lines of SID_FEM files that omit zeros), the modal matrices and the label "
                    "frequencies, plus the FE comparisons stored by 'sidprep reduce'. Exit status 0: "
                    "all checks of severity 'error' pass; 1: one fails; 2: the file cannot be read "
                    "(or is damaged: a SID_FEM file that writes its zeros lacks an entry).")
    p.add_argument("file", metavar="FILE", help=".sid.h5 or .SID_FEM file")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from sidprep.sid.checks import checks_summary, failed_checks, format_checks
    from sidprep.sid.summary import check_sid

    checks = check_sid(args.file)
    if not args.quiet:
        print(format_checks(checks))
    print(f"{args.file}: {checks_summary(checks)}")
    return 1 if failed_checks(checks) else 0
