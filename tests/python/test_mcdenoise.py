"""import mcdenoise from Debian's /usr/bin/python3: ops take and return OpenImageIO.ImageBuf."""
import os
import sys
import tempfile
import unittest

import OpenImageIO as oiio

import mcdenoise

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data")
BOX = os.path.join(DATA, "box16")
# OIDN's published weights, for measurement only (../shared/peers/oidn/README.md).
OIDN_WEIGHTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..",
                            "shared", "peers", "oidn")
# The plans below are those without OIDN's weights (mcdn/denoise.h).
os.environ.pop("MCDN_OIDN_WEIGHTS", None)


BOX_FILES = [
    (os.path.join(BOX, "box_0016spp.exr"), "mean"),
    (os.path.join(BOX, "box_0016spp_var.exr"), "variance"),
    (os.path.join(BOX, "box_0016spp_A.exr"), "halfA"),
    (os.path.join(BOX, "box_0016spp_B.exr"), "halfB"),
]


def box_inputs():
    return mcdenoise.read_inputs(BOX_FILES)


class OpsTakeAndReturnImageBufs(unittest.TestCase):
    def setUp(self):
        self.render = box_inputs()
        self.reference = oiio.ImageBuf(os.path.join(BOX, "box_ref.exr"))

    def test_read_inputs_returns_an_oiio_imagebuf(self):
        self.assertIsInstance(self.render, oiio.ImageBuf)
        self.assertEqual(self.render.spec().width, 64)
        self.assertIn("variance.ViewLayer.Combined.R", self.render.spec().channelnames)

    def test_seed_renders_are_read_with_their_variance(self):
        seeds = mcdenoise.read_inputs([
            (os.path.join(BOX, "box_0016spp_A.exr"), "seed"),
            (os.path.join(BOX, "box_0016spp_B.exr"), "seed"),
        ])
        names = seeds.spec().channelnames
        self.assertIn("variance.ViewLayer.Combined.R", names)
        self.assertIn("A.ViewLayer.Combined.R", names)
        denoised = mcdenoise.nfor(seeds, preset="cycles")
        self.assertLess(mcdenoise.metrics(denoised, self.reference)["relmse"],
                        0.5 * mcdenoise.metrics(seeds, self.reference)["relmse"])
        with self.assertRaisesRegex(RuntimeError, "two or more"):
            mcdenoise.read_inputs([(os.path.join(BOX, "box_0016spp_A.exr"), "seed")])

    def test_progress_is_of_the_whole_run_and_can_cancel(self):
        # One fraction of the whole chain, never going back between its stages (issue 46).
        calls = []
        mcdenoise.denoise(self.render, settings={"cnn.tile": "32"},
                          progress=lambda stage, fraction: calls.append((stage, fraction)))
        fractions = [f for _, f in calls]
        self.assertEqual(fractions, sorted(fractions), calls)
        self.assertEqual(fractions[-1], 1.0)
        self.assertEqual([s for s, _ in calls][0], "cnn")
        self.assertIn("mix", [s for s, _ in calls])

        # An exception in the callback cancels the run and comes out of it; True cancels.
        class Stop(Exception):
            pass

        def stop(stage, fraction):
            raise Stop(stage)

        with self.assertRaisesRegex(Stop, "cnn"):
            mcdenoise.denoise(self.render, progress=stop)
        with self.assertRaisesRegex(RuntimeError, "prefilter: cancelled by the progress callback"):
            mcdenoise.run_chain(self.render, "prefilter,nfor", progress=lambda stage, f: True)

    def test_nfor_denoises(self):
        noisy = mcdenoise.metrics(self.render, self.reference)
        denoised = mcdenoise.nfor(self.render, preset="cycles")
        self.assertIsInstance(denoised, oiio.ImageBuf)
        after = mcdenoise.metrics(denoised, self.reference)
        self.assertLess(after["relmse"], 0.5 * noisy["relmse"])
        self.assertEqual(denoised.nchannels, self.render.nchannels)

    def test_nfor_takes_neighbouring_frames(self):
        # Frames with Blender's Vector pass (a still camera); the neighbours are box16 with
        # its halves swapped: other noise on the same picture.
        def with_motion(image):
            n = image.nchannels
            names = list(image.spec().channelnames) + ["ViewLayer.Vector." + c for c in "XYZW"]
            return oiio.ImageBufAlgo.channels(image, tuple(range(n)) + (0.0,) * 4,
                                              newchannelnames=tuple(names))
        swapped = with_motion(mcdenoise.read_inputs([
            (os.path.join(BOX, "box_0016spp.exr"), "mean"),
            (os.path.join(BOX, "box_0016spp_var.exr"), "variance"),
            (os.path.join(BOX, "box_0016spp_B.exr"), "halfA"),
            (os.path.join(BOX, "box_0016spp_A.exr"), "halfB"),
        ]))
        frame = with_motion(self.render)
        single = mcdenoise.nfor(frame, preset="cycles")
        cross = mcdenoise.nfor(frame, preset="cycles", previous=[swapped], next=[swapped])
        self.assertIsInstance(cross, oiio.ImageBuf)
        self.assertNotEqual(single.get_pixels(oiio.FLOAT).tobytes(),
                            cross.get_pixels(oiio.FLOAT).tobytes())
        self.assertLess(mcdenoise.metrics(cross, self.reference)["relmse"],
                        0.5 * mcdenoise.metrics(self.render, self.reference)["relmse"])
        with self.assertRaisesRegex(RuntimeError, "motion"):
            mcdenoise.nfor(self.render, preset="cycles", previous=[self.render])
        cnn = mcdenoise.cnn(frame, preset="cycles", previous=[swapped], next=[swapped])
        self.assertLess(mcdenoise.metrics(cnn, self.reference)["relmse"],
                        0.5 * mcdenoise.metrics(self.render, self.reference)["relmse"])

    def test_nfor_outlier_modes(self):
        # box16 has no heavy-tailed pixel: every mode gives the same image; a bad mode raises.
        default = mcdenoise.nfor(self.render, preset="cycles").get_pixels(oiio.FLOAT)
        off = mcdenoise.nfor(self.render, preset="cycles", outliers="off").get_pixels(oiio.FLOAT)
        self.assertTrue((default == off).all())
        with self.assertRaises(Exception):
            mcdenoise.nfor(self.render, preset="cycles", outliers="sometimes")

    def test_skip_passes_converged_tiles_through(self):
        # Variance 0 everywhere: every tile is converged (mcdn/skip.h). Without skipping the
        # safety net would find the render exact and every tile worse: off here.
        spec = self.render.spec()
        names = list(spec.channelnames)
        pixels = self.render.get_pixels(oiio.FLOAT)
        for c in "RGB":
            pixels[:, :, names.index("variance.ViewLayer.Combined." + c)] = 0.0
        converged = oiio.ImageBuf(spec)
        converged.set_pixels(oiio.ROI(), pixels)
        colour = [names.index("ViewLayer.Combined." + c) for c in "RGB"]
        skipped = mcdenoise.nfor(converged, skip=True).get_pixels(oiio.FLOAT)[:, :, colour]
        filtered = mcdenoise.nfor(converged, skip=False, fallback=False)
        filtered = filtered.get_pixels(oiio.FLOAT)[:, :, colour]
        self.assertTrue((skipped == pixels[:, :, colour]).all())
        self.assertFalse((filtered == pixels[:, :, colour]).all())

    def test_cnn_denoises(self):
        noisy = mcdenoise.metrics(self.render, self.reference)
        after = mcdenoise.metrics(mcdenoise.cnn(self.render), self.reference)
        self.assertLess(after["relmse"], 0.5 * noisy["relmse"])
        # The workers kept for the next call: freed on request, and the next call loads anew.
        mcdenoise.release_cnn_workers()
        again = mcdenoise.metrics(mcdenoise.cnn(self.render), self.reference)
        self.assertEqual(again["relmse"], after["relmse"])

    def test_denoise_picks_the_chain_and_denoises(self):
        # The render has half buffers: NFOR is weighed beside the CNN (mcdn/choose.h).
        self.assertTrue(mcdenoise.plan(self.render).startswith("cnn -> sure -> choose (nfor) -> mix (net)"))
        noisy = mcdenoise.metrics(self.render, self.reference)
        after = mcdenoise.metrics(mcdenoise.denoise(self.render), self.reference)
        self.assertLess(after["relmse"], 0.5 * noisy["relmse"])
        with self.assertRaises(RuntimeError):
            mcdenoise.denoise(self.render, settings={"cnn.tiles": "256"})  # misspelt key

    def test_read_inputs_for_a_chain_reads_what_its_stages_read(self):
        # Of the variance and half files only the faces the chain's stages read, as mcdntool
        # reads them; its output the same as from every channel.
        written = list(oiio.ImageBuf(BOX_FILES[0][0]).spec().channelnames)
        for chain, halves in (("cnn", False), ("prefilter,nfor", True)):
            chosen = mcdenoise.read_inputs(BOX_FILES, chain=chain)
            names = chosen.spec().channelnames
            self.assertLess(len(names), len(self.render.spec().channelnames), chain)
            self.assertEqual(any(n.startswith("A.") for n in names), halves, chain)
            outputs = [oiio.ImageBufAlgo.channels(mcdenoise.run_chain(image, chain),
                                                  tuple(written))
                       for image in (chosen, self.render)]
            self.assertEqual(outputs[0].get_pixels(oiio.FLOAT).tobytes(),
                             outputs[1].get_pixels(oiio.FLOAT).tobytes(), chain)
        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.read_inputs(BOX_FILES, chain="nfor,nosuch")
        self.assertIn("nosuch", str(caught.exception))

    def test_run_chain_runs_the_stage_tables_stages_by_name(self):
        by_name = mcdenoise.run_chain(self.render, "cnn")
        self.assertEqual(by_name.get_pixels(oiio.FLOAT).tobytes(),
                         mcdenoise.cnn(self.render).get_pixels(oiio.FLOAT).tobytes())
        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.run_chain(self.render, "mix")
        self.assertIn("mix needs sure before it", str(caught.exception))
        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.run_chain(self.render, "oidn", settings={"oidn.weights": "/nonexistent"})
        self.assertIn("$MCDN_OIDN_WEIGHTS", str(caught.exception))
        self.assertIn("RenderKit/oidn-weights", str(caught.exception))

    @unittest.skipUnless(os.path.exists(os.path.join(OIDN_WEIGHTS, "rt_hdr_alb_nrm.tza")),
                         "no ../shared/peers/oidn")
    def test_oidn_sure_mix_by_name(self):
        noisy = mcdenoise.metrics(self.render, self.reference)
        out = mcdenoise.run_chain(self.render, "oidn,sure,mix",
                                  settings={"oidn.weights": OIDN_WEIGHTS})
        self.assertIn("sure.R", out.spec().channelnames)
        after = mcdenoise.metrics(out, self.reference)
        self.assertLess(after["relmse"], 0.5 * noisy["relmse"])

    def test_chain_prefilter_nfor_sure_mix(self):
        out = mcdenoise.prefilter(self.render)
        out = mcdenoise.sure(out, denoiser="nfor")
        self.assertIn("sure.R", out.spec().channelnames)
        mixed = mcdenoise.mix(out, model="analytic", alpha=True)
        self.assertIn("mix.alpha.G", mixed.spec().channelnames)

    def test_sure_takes_a_python_denoiser(self):
        calls = []

        def denoise(buf):
            calls.append(1)
            return mcdenoise.nfor(buf)

        out = mcdenoise.sure(self.render, denoiser=denoise, probes=2)
        self.assertEqual(len(calls), 3)  # K + 1 runs
        self.assertIn("sure.divergence.B", out.spec().channelnames)

    def test_a_denoiser_that_returns_nan_is_an_error(self):
        # Its non-colour channels would become sure's output: NaN must not leave the op.
        def broken(buf):
            pixels = buf.get_pixels(oiio.FLOAT)
            pixels[:, :, :] = float("nan")
            out = oiio.ImageBuf(buf.spec())
            out.set_pixels(oiio.ROI(), pixels)
            return out

        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.sure(self.render, denoiser=broken)
        self.assertIn("the denoiser returned", str(caught.exception))
        self.assertIn("NaN or Inf", str(caught.exception))

    def test_errors_raise_with_the_library_message(self):
        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.read_inputs([("/nonexistent/frame.exr", "mean")])
        self.assertIn("/nonexistent/frame.exr: no such file", str(caught.exception))
        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.nfor(self.render, preset="generic")
        self.assertIn("color", str(caught.exception))
        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.nfor(self.render, window=4)
        self.assertIn("nfor: window=4 must be an odd width", str(caught.exception))
        with self.assertRaises(RuntimeError) as caught:
            mcdenoise.mix(self.render)
        self.assertIn("run --sure before it", str(caught.exception))

    def test_write_is_atomic_and_keeps_the_render_channels(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "out.exr")
            mcdenoise.write(mcdenoise.nfor(self.render), path, datatype="half")
            self.assertEqual(os.listdir(tmp), ["out.exr"])
            written = oiio.ImageBuf(path)
            self.assertEqual(written.nchannels, 39)

    def test_write_never_replaces_an_input(self):
        # tests/robustness: the same for mcdntool. Here on copies, never the fixtures.
        with tempfile.TemporaryDirectory() as tmp:
            paths = {}
            for kind, name in (("mean", "box_0016spp.exr"), ("variance", "box_0016spp_var.exr")):
                paths[kind] = os.path.join(tmp, name)
                with open(os.path.join(BOX, name), "rb") as src, open(paths[kind], "wb") as dst:
                    dst.write(src.read())
            before = {k: open(p, "rb").read() for k, p in paths.items()}
            render = mcdenoise.read_inputs(list((p, k) for k, p in paths.items()))
            for path in paths.values():
                with self.assertRaises(RuntimeError) as caught:
                    mcdenoise.write(mcdenoise.cnn(render), path)
                self.assertIn("also an input", str(caught.exception))
            self.assertEqual({k: open(p, "rb").read() for k, p in paths.items()}, before)
            with self.assertRaises(RuntimeError) as caught:
                mcdenoise.write(render, os.path.join(tmp, "out.exr"), datatype="int8")
            self.assertIn("datatype", str(caught.exception))

    def test_thread_counts_follow_the_librarys_rule(self):
        for n in (70000, 65537, -5):
            with self.assertRaises(RuntimeError) as caught:
                mcdenoise.cnn(self.render, nthreads=n)
            self.assertIn("threads=%d" % n, str(caught.exception))
        with self.assertRaises(RuntimeError):
            mcdenoise.nfor(self.render, nthreads=70000)

    def test_temporal_metrics(self):
        # The render moved 2 px right between frames (each pixel was 2 px left of where it is),
        # its error with it: no flicker with the motion vectors, some without.
        shift = lambda img, dx: oiio.ImageBufAlgo.cut(img, oiio.ROI(dx, dx + 96, 0, 96, 0, 1, 0, 3))
        x0, x1 = shift(self.render, 2), shift(self.render, 0)
        r0, r1 = shift(self.reference, 2), shift(self.reference, 0)
        spec = oiio.ImageSpec(96, 96, 2, oiio.FLOAT)
        motion = oiio.ImageBuf(spec)
        oiio.ImageBufAlgo.fill(motion, (-2.0, 0.0))
        still = mcdenoise.temporal_metrics(x1, x0, r1, r0, motion)
        self.assertLess(still["mse"], 1e-12)
        self.assertEqual(still["pixels"], 94 * 96)
        self.assertGreater(mcdenoise.temporal_metrics(x1, x0, r1, r0)["mse"], 1e-6)
        with self.assertRaises(RuntimeError):
            mcdenoise.temporal_metrics(x1, x0, r1, r0, motion, motion_channels=[0])
        # The references' own noise, from a variance of the mean of 0.01 on every pixel: v per
        # frame, v + v for a pair of frames moved by whole pixels.
        variance = oiio.ImageBuf(oiio.ImageSpec(96, 96, 3, oiio.FLOAT))
        oiio.ImageBufAlgo.fill(variance, (0.01, 0.01, 0.01))
        per_frame = mcdenoise.metrics(x1, r1, reference_variance=variance)
        self.assertAlmostEqual(per_frame["mse_reference_noise"], 0.01, places=9)
        self.assertGreater(per_frame["relmse_reference_noise"], 0.01)
        pair = mcdenoise.temporal_metrics(x1, x0, r1, r0, motion, reference_variance=variance,
                                          previous_reference_variance=variance)
        self.assertAlmostEqual(pair["mse_reference_noise"], 0.02, places=9)
        self.assertNotIn("mse_reference_noise", still)
        with self.assertRaises(RuntimeError):
            mcdenoise.temporal_metrics(x1, x0, r1, r0, motion, reference_variance=variance)


def with_value(image, channel, value, x=7, y=5):
    """A copy of `image` with `channel` of pixel (x, y) set to `value`."""
    out = oiio.ImageBuf(image.spec())
    out.copy(image, oiio.FLOAT)
    c = out.spec().channelindex(channel)
    assert c >= 0, channel
    pixel = list(out.getpixel(x, y))
    pixel[c] = value
    out.setpixel(x, y, pixel)
    return out


class BadInputRaisesInEveryOp(unittest.TestCase):
    """What mcdntool and the plugin refuse, every op refuses (one validation, issue 43)."""

    OPS = {
        "denoise": lambda i: mcdenoise.denoise(i),
        "cnn": lambda i: mcdenoise.cnn(i),
        "nfor": lambda i: mcdenoise.nfor(i),
        "prefilter": lambda i: mcdenoise.prefilter(i),
        "sure": lambda i: mcdenoise.sure(i, denoiser="nfor"),
    }

    def setUp(self):
        self.render = box_inputs()

    def test_values_no_render_holds(self):
        cases = [
            ("ViewLayer.Combined.R", float("inf"), "Inf"),
            ("ViewLayer.Combined.G", float("nan"), "NaN"),
            ("ViewLayer.Combined.B", -1e30, "huge value"),
            ("ViewLayer.Combined.R", 1e16, "huge value"),
            ("variance.ViewLayer.Combined.G", -1.0, "negative variance"),
            ("variance.ViewLayer.Combined.G", float("nan"), "NaN"),
            ("A.ViewLayer.Combined.R", float("nan"), "NaN"),
            ("ViewLayer.Denoising Depth.Z", float("nan"), "NaN"),
            ("ViewLayer.Denoising Normal.X", float("inf"), "Inf"),
            ("ViewLayer.Denoising Normal.X", 1e10, "a normal of length"),
        ]
        for channel, value, problem in cases:
            image = with_value(self.render, channel, value)
            for name, op in self.OPS.items():
                with self.subTest(channel=channel, value=value, op=name):
                    with self.assertRaises(RuntimeError) as caught:
                        op(image)
                    self.assertIn("channel '%s'" % channel, str(caught.exception))
                    self.assertIn(problem, str(caught.exception))

    def test_what_is_not_a_file_raises_at_once(self):
        with tempfile.TemporaryDirectory() as tmp:
            fifo = os.path.join(tmp, "fifo.exr")
            os.mkfifo(fifo)
            for path, what in ((fifo, "a FIFO"), ("/dev/zero", "a device")):
                with self.subTest(path=path):
                    with self.assertRaises(RuntimeError) as caught:
                        mcdenoise.read_inputs([(path, "mean")])
                    self.assertIn(path + ": not a regular file (" + what, str(caught.exception))

    def test_halves_of_another_render_raise(self):
        render = box_inputs()
        mirrored = oiio.ImageBufAlgo.flip(render)
        names = render.spec().channelnames
        # The render's own channels from box16, the halves from the mirrored frame.
        both = oiio.ImageBufAlgo.channel_append(render, mirrored)
        picks = tuple(i + (render.nchannels if names[i].startswith(("A.", "B.")) else 0)
                      for i in range(render.nchannels))
        image = oiio.ImageBufAlgo.channels(both, picks, newchannelnames=tuple(names))
        image.specmod().attribute("mcdn:inputs", render.spec().get_string_attribute("mcdn:inputs"))
        for name in ("nfor", "prefilter", "sure"):
            with self.subTest(op=name):
                with self.assertRaises(RuntimeError) as caught:
                    self.OPS[name](image)
                self.assertIn("the halves' mean is not the render", str(caught.exception))

    def test_a_corrupt_block_in_a_half_is_a_warning_not_the_image(self):
        image = self.render
        for y in range(8, 11):  # inside one 32x32 tile of the four
            for x in range(8, 11):
                image = with_value(image, "A.ViewLayer.Combined.R", 1e6, x, y)
        with self.assertWarns(RuntimeWarning) as caught:
            out = mcdenoise.nfor(image)
        self.assertIn("the half buffers disagree with the render", str(caught.warning))
        stats = oiio.ImageBufAlgo.computePixelStats(out)
        r = out.spec().channelindex("ViewLayer.Combined.R")
        self.assertLess(stats.max[r], 100.0)


if __name__ == "__main__":
    unittest.main(verbosity=2)
