"""A program's ``main`` run in the test's own process, as its tests call it to read what it
says (a refusal's one line, a listing) without starting a Python child for it."""
import contextlib
import io


def run_main(main, argv):
    """``main(argv)``: (exit status, what it printed on stdout, on stderr). argparse's exit on
    a bad option counts as the exit status."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main(list(argv))
        except SystemExit as stop:
            status = stop.code
    return status, out.getvalue(), err.getvalue()
