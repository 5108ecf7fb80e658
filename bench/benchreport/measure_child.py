"""Runs one command and prints its wall time, CPU time, peak RSS and exit code as JSON.

  /usr/bin/python3 -S measure_child.py LOG -- COMMAND ARGS...

Why a separate small process: Linux carries a process's peak RSS across exec, so a child
forked straight from the report (a Python with OpenImageIO and matplotlib loaded, ~180 MB)
would report at least the report's own size. Forked from this bare interpreter instead, the
floor is a few MB, below what any mcdntool run uses.
"""
import json
import os
import sys
import time


def main():
    log_path, separator, argv = sys.argv[1], sys.argv[2], sys.argv[3:]
    if separator != "--" or not argv:
        sys.exit("usage: measure_child.py LOG -- COMMAND ARGS...")
    log = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    start = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        os.dup2(log, 1)
        os.dup2(log, 2)
        try:
            os.execv(argv[0], argv)
        except OSError as error:
            os.write(2, f"measure_child.py: {argv[0]}: {error}\n".encode())
        os._exit(127)
    _, status, usage = os.wait4(pid, 0)
    wall = time.perf_counter() - start
    print(json.dumps({"exit": os.waitstatus_to_exitcode(status), "wall_s": wall,
                      "cpu_s": usage.ru_utime + usage.ru_stime,
                      "peak_rss_mb": usage.ru_maxrss / 1024.0}))


if __name__ == "__main__":
    main()
