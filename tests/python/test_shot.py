"""python3 -m mcdenoise.shot on a real Dask cluster: a dask-scheduler and two dask-worker
processes on localhost, as a shot runs on machines of a studio. The files it writes are the
plain CLI's (mcdntool --frames over the whole shot); a chunk that fails is retried, reported
and makes the exit status 1, the other chunks' frames are written.

  test_shot.py --build BUILD      (PYTHONPATH holds BUILD/python; exit 77 without Dask)
"""
import argparse
import glob
import os
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BOX = os.path.join(REPO, "examples", "box")
FACES = {"": "mean", "_var": "variance", "_A": "halfA", "_B": "halfB"}
FRAMES = 8


def shot_inputs(folder):
    """FRAMES frames of the box render, frame f's colour scaled by 1 + f/10 (its variance by
    the square), as render.#.exr and its variance and halves."""
    import OpenImageIO as oiio
    os.makedirs(folder, exist_ok=True)
    for suffix in FACES:
        src = oiio.ImageBuf(os.path.join(BOX, f"box_0016spp{suffix}.exr"))
        for f in range(1, FRAMES + 1):
            scale = 1 + f / 10 if suffix != "_var" else (1 + f / 10) ** 2
            out = oiio.ImageBufAlgo.mul(src, scale)
            assert out.write(os.path.join(folder, f"render{suffix}.{f:04d}.exr"), "float")
    args = []
    for suffix, kind in FACES.items():
        args += [f"-i:as={kind}", os.path.join(folder, f"render{suffix}.#.exr")]
    return args


def same_pixels(a, b):
    import OpenImageIO as oiio
    x, y = oiio.ImageBuf(a), oiio.ImageBuf(b)
    return (x.spec().channelnames == y.spec().channelnames
            and oiio.ImageBufAlgo.compare(x, y, 0, 0).maxerror == 0)


class Shot(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="mcdn-shot-")
        cls.tool = os.path.join(ARGS.build, "bin", "mcdntool")
        cls.inputs = shot_inputs(os.path.join(cls.tmp, "in"))
        cls.stages = ["--threads", "1", "--cnn"]
        # The plain CLI over the whole shot: what every Dask run must write.
        cls.expected = os.path.join(cls.tmp, "cli")
        os.makedirs(cls.expected)
        subprocess.run([cls.tool, "--frames", f"1-{FRAMES}"] + cls.inputs + cls.stages
                       + ["-o", os.path.join(cls.expected, "out.#.exr")], check=True)
        # A scheduler and two workers, each its own process, as on other machines.
        cls.scheduler_file = os.path.join(cls.tmp, "scheduler.json")
        python = ["/usr/bin/python3", "-m"]
        env = dict(os.environ)
        cls.processes = [subprocess.Popen(
            python + ["distributed.cli.dask_scheduler", "--scheduler-file", cls.scheduler_file,
                      "--host", "127.0.0.1", "--port", "0", "--dashboard-address", ":0"],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
        deadline = time.time() + 60
        while not os.path.exists(cls.scheduler_file) and time.time() < deadline:
            time.sleep(0.2)
        for _ in range(2):
            cls.processes.append(subprocess.Popen(
                python + ["distributed.cli.dask_worker", "--scheduler-file", cls.scheduler_file,
                          "--nthreads", "1", "--nworkers", "1", "--no-nanny",
                          "--dashboard-address", ":0"],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client
        with Client(scheduler_file=cls.scheduler_file, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)

    @classmethod
    def tearDownClass(cls):
        for p in reversed(cls.processes):
            p.terminate()
        for p in cls.processes:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def shot(self, name, extra, inputs=None):
        out = os.path.join(self.tmp, name)
        os.makedirs(out)
        command = ["/usr/bin/python3", "-m", "mcdenoise.shot", "--frames", f"1-{FRAMES}",
                   "--chunk", "3", "--mcdntool", self.tool, "--logs", os.path.join(out, "logs")]
        command += extra + ["--"] + (inputs or self.inputs) + self.stages
        command += ["-o", os.path.join(out, "out.#.exr")]
        run = subprocess.run(command, capture_output=True, text=True, timeout=600)
        return out, run

    def test_on_a_scheduler_and_two_workers_as_the_cli_writes(self):
        out, run = self.shot("dask", ["--scheduler-file", self.scheduler_file])
        self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
        for f in range(1, FRAMES + 1):
            name = f"out.{f:04d}.exr"
            self.assertTrue(same_pixels(os.path.join(out, name),
                                        os.path.join(self.expected, name)), name)
        # One log per chunk (1-3, 4-6, 7-8), each with mcdntool's exit status.
        logs = sorted(os.path.basename(p) for p in glob.glob(os.path.join(out, "logs", "*")))
        self.assertEqual(logs, ["frames_1-3.log", "frames_4-6.log", "frames_7-8.log"])
        for log in logs:
            with open(os.path.join(out, "logs", log)) as f:
                self.assertIn("# exit status 0", f.read())
        self.assertIn("frames 4-6 done", run.stdout)
        self.assertEqual(len(os.listdir(out)), FRAMES + 1, os.listdir(out))  # no temporary

    def test_a_failing_chunk_is_retried_reported_and_the_others_written(self):
        # Frame 5's render is missing: chunk 4-6 fails on every try, 1-3 and 7-8 succeed.
        inputs = shot_inputs(os.path.join(self.tmp, "broken"))
        os.remove(os.path.join(self.tmp, "broken", "render.0005.exr"))
        out, run = self.shot("failing", ["--scheduler-file", self.scheduler_file,
                                         "--retries", "1"], inputs)
        self.assertEqual(run.returncode, 1, run.stdout + run.stderr)
        self.assertIn("frames 4-6", run.stderr)
        self.assertIn("render.0005.exr", run.stderr)
        for f in (1, 2, 3, 7, 8):
            self.assertTrue(os.path.exists(os.path.join(out, f"out.{f:04d}.exr")), f)
        self.assertFalse(os.path.exists(os.path.join(out, "out.0005.exr")))

    def test_a_local_cluster_without_a_scheduler(self):
        out, run = self.shot("local", ["--workers", "2"])
        self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
        for f in range(1, FRAMES + 1):
            name = f"out.{f:04d}.exr"
            self.assertTrue(same_pixels(os.path.join(out, name),
                                        os.path.join(self.expected, name)), name)


class WithoutDask(unittest.TestCase):
    def test_a_missing_distributed_is_said_with_what_to_install(self):
        # As on a machine without python3-distributed: the import fails.
        code = ("import sys; sys.modules['distributed'] = None; from mcdenoise import shot; "
                "sys.exit(shot.main(['--mcdntool', sys.argv[1], '--frames', '1', '--', "
                "'-i', 'x.#.exr', '-o', 'y.#.exr']))")
        tool = os.path.join(ARGS.build, "bin", "mcdntool")
        run = subprocess.run([sys.executable, "-c", code, tool], capture_output=True, text=True)
        self.assertEqual(run.returncode, 2, run.stderr)
        self.assertIn("python3-distributed", run.stderr)
        self.assertNotIn("Traceback", run.stderr)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", required=True)
    ARGS, rest = ap.parse_known_args()
    try:
        import distributed  # noqa: F401
    except ImportError:
        print("test_shot: skipped: Dask distributed is not installed (python3-distributed)")
        sys.exit(77)
    unittest.main(argv=[sys.argv[0]] + rest)
