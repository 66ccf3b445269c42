"""The verdict the run-file check scripts end with (imported from their folder)."""


def report(problems, ok_line, tag="FAIL:", most=30, quiet=False):
    """Prints the first `most` problems (none when quiet) and returns 1, or, when there are no
    problems, prints ok_line and returns 0: the script's exit status."""
    if problems:
        if not quiet:
            for p in problems[:most]:
                print(tag, p)
        return 1
    print(ok_line)
    return 0
