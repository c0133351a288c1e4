"""Run a command as the terminal's foreground job, as an interactive shell runs one, and exit
with its status: ``python3 tools/foreground.py roslaunch ros_hrc hrc.launch ...``.

Why: `make run` ran roslaunch in make's own process group, so Ctrl-C (SIGINT to the terminal's
foreground group) reached make too. roslaunch stops its processes and exits 0, but make, after
waiting for it, ends by its own SIGINT: the user's shell saw status 130 where plain roslaunch
gives 0. Here the command gets a process group of its own and the terminal is handed to it
(``tcsetpgrp``): Ctrl-C reaches roslaunch and its nodes alone, as it does when roslaunch is
typed at the prompt, and make ends with roslaunch's status. The terminal is taken back when
the command ends (a job-control shell does the same for each job).

Without a controlling terminal in the foreground (stdin not a terminal, or this job in the
background), nothing is handed over: the command replaces this process (exec), in the
caller's process group, as before.
"""
import os
import signal
import sys


def terminal_in_foreground() -> bool:
    """Whether stdin is a terminal whose foreground process group is this process's."""
    try:
        return os.isatty(0) and os.tcgetpgrp(0) == os.getpgrp()
    except OSError:
        return False


def main(argv) -> int:
    if not argv:
        print("usage: foreground.py COMMAND [ARGUMENT ...]", file=sys.stderr)
        return 2
    if not terminal_in_foreground():
        os.execvp(argv[0], argv)
    own_group = os.getpgrp()
    # A process group that is not the terminal's foreground one gets SIGTTOU when it sets the
    # foreground: ignored here, as shells do, to take the terminal back at the end.
    signal.signal(signal.SIGTTOU, signal.SIG_IGN)

    def take_terminal():     # in the child, before exec: its group is the foreground one
        os.setpgid(0, 0)
        os.tcsetpgrp(0, os.getpgrp())
        signal.signal(signal.SIGTTOU, signal.SIG_DFL)

    pid = os.fork()
    if pid == 0:
        try:
            take_terminal()
            os.execvp(argv[0], argv)
        except OSError as error:
            print(f"{argv[0]}: {error.strerror or error}", file=sys.stderr)
        os._exit(127)
    try:
        os.setpgid(pid, pid)          # also here: whichever runs first, the group exists
    except OSError:
        pass                          # the child has exec'd (it set its group itself)
    # Signals sent to this process (a hang-up, a kill of make's group) go on to the command.
    for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(number, lambda received, _frame: os.killpg(pid, received))
    _, status = os.waitpid(pid, 0)     # (retried after a signal's handler, PEP 475)
    try:
        os.tcsetpgrp(0, own_group)
    except OSError:
        pass                          # the terminal is gone (a hang-up): nobody to give it to
    return os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) \
        else 128 + os.WTERMSIG(status)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
