"""``hrc_pomdp`` in a child process with hard resource limits, for the tests that feed it
inputs that once made it allocate tens of gigabytes: a regression then fails the test (the
child gets a MemoryError, or EFBIG) instead of eating the shared machine."""
import os
import resource
import signal
import subprocess
import sys
from typing import Optional, Sequence

GiB = 1 << 30


def run_hrc_pomdp(args: Sequence[str], address_space: int = 2 * GiB,
                  file_size: Optional[int] = None, cwd=None,
                  timeout: float = 300.0) -> subprocess.CompletedProcess:
    """Run ``python -m ros_hrc.commands.pomdp ARGS`` with its virtual memory capped at
    ``address_space`` bytes (RLIMIT_AS) and, if given, every file it writes at ``file_size``
    bytes (RLIMIT_FSIZE). ``timeout`` only guards against a hang; no test asserts a time."""
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
        if file_size is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)      # EFBIG instead of a signal
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size, file_size))

    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-m", "ros_hrc.commands.pomdp", *args], cwd=cwd, env=env,
                          preexec_fn=limit, capture_output=True, text=True, timeout=timeout)
