"""Denoise a shot on a Dask cluster: the frames in chunks, one task per chunk, each task one
mcdntool command line, as a render farm runs it.

  python3 -m mcdenoise.shot --frames 1-1000 [--chunk 10] [--scheduler tcp://host:8786 |
      --scheduler-file FILE | --workers N] [--retries 2] [--logs DIR] [--mcdntool PATH]
      -- MCDNTOOL ARGUMENTS (file names with #, @ or %04d, e.g. -i render.#.exr ... -o out.#.exr)

Each chunk runs `mcdntool --frames FIRST-LAST --skip-existing ARGUMENTS` on a worker, in the
folder the shot was started in, so the workers must see the same paths (shared storage, as
a farm's nodes do). A chunk that
fails (mcdntool exits non-zero, or its worker dies) is run again, up to --retries times;
--skip-existing makes a retry redo only the frames it has not written, and mcdntool's
atomic outputs mean a killed chunk leaves no partial file. Each chunk's output goes to
LOGS/frames_FIRST-LAST.log. Without --scheduler or --scheduler-file the chunks run on a
local cluster of --workers processes on this machine. The exit status is 0 when every chunk
succeeded, 1 when some failed after their retries (they are listed), 2 for a bad command line.
"""
import argparse
import os
import shutil
import subprocess
import sys
import time


def frame_list(spec):
    """The frames of a spec as mcdntool's --frames reads it: 1-10, 1-100x5, 3,7,9."""
    frames = []
    for part in spec.split(","):
        part = part.strip()
        step = 1
        if "x" in part:
            part, step_text = part.split("x", 1)
            step = int(step_text)
        if "-" in part[1:]:
            cut = part.index("-", 1)
            first, last = int(part[:cut]), int(part[cut + 1:])
        else:
            first = last = int(part)
        if step < 1 or last < first:
            raise ValueError(f"--frames {spec}: not a frame range (e.g. 1-10, 1-100x5, 3,7,9)")
        frames.extend(range(first, last + 1, step))
    return frames


def chunks(frames, size):
    """Consecutive frames in chunks of at most `size`, each as mcdntool's --frames spec."""
    out = []
    for i in range(0, len(frames), size):
        part = frames[i:i + size]
        step = part[1] - part[0] if len(part) > 1 else 1
        if all(b - a == step for a, b in zip(part, part[1:])):
            spec = f"{part[0]}-{part[-1]}" + (f"x{step}" if step > 1 else "")
        else:
            spec = ",".join(str(f) for f in part)
        out.append((part[0], part[-1], spec))
    return out


def run_chunk(mcdntool, spec, arguments, log_path, cwd):
    """One farm job: mcdntool on a chunk of frames, in the submitter's folder `cwd` (relative
    names are the submitter's). Raises on failure (Dask then retries)."""
    import socket
    try:
        from distributed import get_worker
        where = f"{socket.gethostname()} ({get_worker().address})"
    except (ImportError, ValueError):
        where = socket.gethostname()
    if not os.path.isdir(cwd):
        raise RuntimeError(f"frames {spec}: {cwd} (the folder the shot was started in) does not "
                           f"exist on {where}: the workers need the same paths")
    command = [mcdntool, "--frames", spec, "--skip-existing"] + list(arguments)
    start = time.time()
    log_path = os.path.join(cwd, log_path)
    os.makedirs(os.path.dirname(log_path) or ".", exist_ok=True)
    with open(log_path + ".part", "w") as log:
        log.write(f"# {where} in {cwd}: {' '.join(command)}\n")
        log.flush()
        code = subprocess.call(command, stdout=log, stderr=subprocess.STDOUT, cwd=cwd)
        log.write(f"# exit status {code} after {time.time() - start:.1f} s\n")
    os.replace(log_path + ".part", log_path)
    if code != 0:
        with open(log_path) as log:
            lines = [l.rstrip() for l in log if not l.startswith("#")]
        last = lines[-1] if lines else "(no output)"
        raise RuntimeError(f"frames {spec}: mcdntool exited with {code}: {last} (log: {log_path})")
    return where, time.time() - start


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if "--" in argv:
        cut = argv.index("--")
        own, arguments = argv[:cut], argv[cut + 1:]
    else:
        own, arguments = argv, []
    ap = argparse.ArgumentParser(prog="python3 -m mcdenoise.shot",
                                 description=__doc__.split("\n\n")[0],
                                 epilog="Everything after -- is mcdntool's command line.")
    ap.add_argument("--frames", required=True, help="the shot's frames: 1-1000, 1-100x5, 3,7,9")
    ap.add_argument("--chunk", type=int, default=10, help="frames per task (default 10)")
    ap.add_argument("--scheduler", help="a running Dask scheduler's address, tcp://host:8786")
    ap.add_argument("--scheduler-file", help="a running Dask scheduler's --scheduler-file")
    ap.add_argument("--workers", type=int, default=1,
                    help="without a scheduler: worker processes of the local cluster (default 1)")
    ap.add_argument("--retries", type=int, default=2,
                    help="times a failed chunk is run again (default 2)")
    ap.add_argument("--logs", default="mcdenoise-logs",
                    help="folder of the chunks' logs, as the workers see it (default mcdenoise-logs)")
    ap.add_argument("--mcdntool", default="mcdntool",
                    help="mcdntool as the workers find it (default: on their PATH)")
    args = ap.parse_args(own)
    if not arguments:
        ap.error("no mcdntool command line after --")
    if args.chunk < 1 or args.retries < 0 or args.workers < 1:
        ap.error("--chunk and --workers must be at least 1, --retries at least 0")
    if args.scheduler and args.scheduler_file:
        ap.error("give --scheduler or --scheduler-file, not both")
    try:
        frames = frame_list(args.frames)
    except ValueError as e:
        ap.error(str(e))
    mcdntool = args.mcdntool
    if os.sep in mcdntool:
        mcdntool = os.path.abspath(mcdntool)
    elif not (args.scheduler or args.scheduler_file) and not shutil.which(mcdntool):
        ap.error(f"{mcdntool}: not found on PATH (give --mcdntool)")
    logs = os.path.abspath(args.logs)

    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        print("mcdenoise.shot: error: the shot runner needs Dask's distributed "
              "(apt-get install python3-distributed, or pip install distributed); "
              "mcdntool --frames runs a shot on one machine without it", file=sys.stderr)
        return 2
    cluster = None
    if args.scheduler:
        client = Client(args.scheduler)
    elif args.scheduler_file:
        client = Client(scheduler_file=args.scheduler_file)
    else:
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    planned = chunks(frames, args.chunk)
    print(f"mcdenoise.shot: {len(frames)} frames in {len(planned)} chunks of up to {args.chunk} "
          f"on {client.scheduler.address}, logs in {logs}", flush=True)
    futures = {}
    for first, last, spec in planned:
        log = os.path.join(logs, f"frames_{first}-{last}.log")
        future = client.submit(run_chunk, mcdntool, spec, arguments, log, os.getcwd(),
                               retries=args.retries,
                               pure=False, key=f"mcdenoise-frames-{first}-{last}-{time.time_ns()}")
        futures[future] = spec
    failed = []
    done = 0
    start = time.time()
    for future in as_completed(futures):
        spec = futures[future]
        done += 1
        if future.status == "finished":
            host, seconds = future.result()
            print(f"mcdenoise.shot: frames {spec} done on {host} in {seconds:.1f} s "
                  f"({done}/{len(futures)}, {time.time() - start:.0f} s)", flush=True)
        else:
            failed.append(spec)
            print(f"mcdenoise.shot: error: {future.exception()} ({done}/{len(futures)})",
                  file=sys.stderr, flush=True)
    client.close()
    if cluster is not None:
        cluster.close()
    if failed:
        print(f"mcdenoise.shot: {len(failed)} of {len(futures)} chunks failed after "
              f"{args.retries} retries: frames {', '.join(failed)}", file=sys.stderr)
        return 1
    print(f"mcdenoise.shot: {len(frames)} frames in {time.time() - start:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
