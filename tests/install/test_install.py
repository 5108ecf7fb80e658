"""`cmake --install` into a temporary prefix, the installed tree moved elsewhere, and every
front end run from there: mcdntool, plain oiiotool with the plugin, `import mcdenoise` and a
user's CMake project (find_package) and pkg-config build. Each must find the library, the
models and the colour config of the moved tree (never the build or source tree's) and give
exactly the build tree's output.

    test_install.py --build BUILD_DIR --version X.Y.Z --plugin-dir BUILD_PLUGIN_DIR
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import OpenImageIO as oiio
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
BOX = os.path.join(HERE, "..", "data", "box16")
RENDER = os.path.join(BOX, "box_0016spp.exr")
REFERENCE = os.path.join(BOX, "box_ref.exr")
ARGS = None


def run(cmd, env=None, cwd=None):
    """Runs cmd, failing the test with its output when it exits non-zero."""
    result = subprocess.run(cmd, env=env, cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        raise AssertionError("%s exited %d:\n%s" % (" ".join(cmd), result.returncode,
                                                     result.stdout))
    return result.stdout


def clean_env(**extra):
    """The environment without anything that points at a tree: what a user has."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("MCDN_MODELS", "OCIO", "OIIO_LIBRARY_PATH", "PYTHONPATH",
                        "LD_LIBRARY_PATH")}
    env.update(extra)
    return env


def pixels(path):
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise AssertionError(buf.geterror())
    return list(buf.spec().channelnames), buf.get_pixels(oiio.FLOAT)


class InstalledTree(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="mcdn-install-")
        staged = os.path.join(cls.tmp, "staged")
        run(["cmake", "--install", ARGS.build, "--prefix", staged])
        # Moved after installing: nothing may remember where it was installed.
        cls.prefix = os.path.join(cls.tmp, "moved", "opt", "mcdenoise")
        os.makedirs(os.path.dirname(cls.prefix))
        shutil.move(staged, cls.prefix)
        libs = [d for d in ("lib", os.path.join("lib", "x86_64-linux-gnu"))
                if os.path.isdir(os.path.join(cls.prefix, d, "mcdenoise"))]
        cls.libdir = os.path.join(cls.prefix, libs[0])
        cls.mcdntool = os.path.join(cls.prefix, "bin", "mcdntool")
        cls.build_tool = os.path.join(ARGS.build, "bin", "mcdntool")
        cls.out = os.path.join(cls.tmp, "out")
        os.makedirs(cls.out)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_installs_every_part(self):
        for part in ["bin/mcdntool", "include/mcdn/cnn.h", "include/mcdn/version.h",
                     "share/mcdenoise/models/kpcn.mcdnw", "share/mcdenoise/models/kpcn_can.mcdnw",
                     "share/mcdenoise/models/mix.mcdnw",
                     "share/mcdenoise/models/mix_cnn.mcdnw", "share/mcdenoise/models/mix_oidn.mcdnw",
                     "share/mcdenoise/ocio/config.ocio"]:
            self.assertTrue(os.path.isfile(os.path.join(self.prefix, part)), part)
        for part in ["libmcdenoise.so", "mcdenoise/mcdn.imageio.so",
                     "cmake/mcdenoise/mcdenoiseConfig.cmake", "pkgconfig/mcdenoise.pc"]:
            self.assertTrue(os.path.exists(os.path.join(self.libdir, part)), part)

    def test_version_is_the_projects(self):
        out = run([self.mcdntool, "--version"], env=clean_env())
        self.assertEqual(out.strip(), "mcdntool " + ARGS.version)

    def test_finds_its_data_in_the_moved_tree(self):
        # --help names the models, colour config and plugin folder the library found,
        # relative to the library file the loader picked (so: the moved one).
        help_text = run([self.mcdntool, "--help"], env=clean_env())
        data = os.path.realpath(os.path.join(self.prefix, "share", "mcdenoise"))
        self.assertIn(os.path.join(data, "models"), help_text)
        self.assertIn(os.path.join(data, "ocio", "config.ocio"), help_text)
        self.assertIn(os.path.realpath(os.path.join(self.libdir, "mcdenoise")), help_text)
        self.assertNotIn(os.path.realpath(ARGS.build), help_text)

    def denoise(self, tool, name, *chain):
        out = os.path.join(self.out, name)
        run([tool, "-i", RENDER, "-i:as=variance", os.path.join(BOX, "box_0016spp_var.exr"),
             "-i:as=halfA", os.path.join(BOX, "box_0016spp_A.exr"), "-i:as=halfB",
             os.path.join(BOX, "box_0016spp_B.exr")] + list(chain) + ["-o", out],
            env=clean_env(), cwd=self.tmp)
        return out

    def test_mcdntool_gives_the_build_trees_output(self):
        for chain in (["--cnn"], ["--cnn", "--sure", "--mix:model=net"]):
            name = "_".join(c.strip("-").replace(":", "").replace("=", "") for c in chain)
            installed = pixels(self.denoise(self.mcdntool, name + "_installed.exr", *chain))
            built = pixels(self.denoise(self.build_tool, name + "_build.exr", *chain))
            self.assertEqual(installed[0], built[0])
            np.testing.assert_array_equal(installed[1], built[1])

    def test_written_files_name_the_software(self):
        out = self.denoise(self.mcdntool, "software.exr", "--cnn")
        software = oiio.ImageBuf(out).spec().get_string_attribute("Software")
        original = oiio.ImageBuf(RENDER).spec().get_string_attribute("Software")
        self.assertEqual(software, original + "; mcdenoise " + ARGS.version)

    def test_plain_oiiotool_reads_a_recipe_with_the_installed_plugin(self):
        recipe = "%s?in=%s&chain=cnn" % (os.path.join(self.tmp, "x.mcdn"), RENDER)
        installed = os.path.join(self.out, "plugin_installed.exr")
        built = os.path.join(self.out, "plugin_build.exr")
        plugin_dirs = {installed: os.path.join(self.libdir, "mcdenoise"),
                       built: ARGS.plugin_dir}
        for out, plugin_dir in plugin_dirs.items():
            run(["oiiotool", recipe, "-d", "float", "-o", out],
                env=clean_env(OIIO_LIBRARY_PATH=plugin_dir), cwd=self.tmp)
        np.testing.assert_array_equal(pixels(installed)[1], pixels(built)[1])
        # The plugin's version, in the spec oiiotool --info shows (oiiotool's own output
        # carries oiiotool's Software, and OIIO's writers drop a format's namespace).
        info = run(["oiiotool", "--info", "-v", recipe],
                   env=clean_env(OIIO_LIBRARY_PATH=plugin_dirs[installed]), cwd=self.tmp)
        self.assertIn('mcdn:Version: "%s"' % ARGS.version, info)
        self.assertIn('mcdenoise %s"' % ARGS.version, info)

    def test_python_module_from_the_moved_tree(self):
        # The package mcdenoise/ (its compiled _mcdenoise and the Python parts): its folder's
        # parent goes on PYTHONPATH.
        site = [os.path.dirname(root) for root, dirs, files in os.walk(self.prefix)
                if os.path.basename(root) == "mcdenoise"
                and any(f.startswith("_mcdenoise.") and f.endswith(".so") for f in files)
                and {"__init__.py", "shot.py"} <= set(files)]
        self.assertEqual(len(site), 1, site)
        script = (
            "import sys, OpenImageIO as oiio, mcdenoise\n"
            "maps = open('/proc/self/maps').read()\n"
            "libs = sorted({l.split()[-1] for l in maps.splitlines() if 'libmcdenoise' in l})\n"
            "print(mcdenoise.__version__); print(mcdenoise.__file__); print(libs)\n"
            "kinds = ['mean', 'variance', 'halfA', 'halfB']\n"
            "buf = mcdenoise.read_inputs(list(zip(sys.argv[1:5], kinds)))\n"
            "mcdenoise.cnn(buf).write(sys.argv[5], 'float')\n")
        out = os.path.join(self.out, "python_installed.exr")
        inputs = [RENDER] + [os.path.join(BOX, "box_0016spp_%s.exr" % k) for k in "var A B".split()]
        printed = run(["/usr/bin/python3", "-c", script] + inputs + [out],
                      env=clean_env(PYTHONPATH=site[0]), cwd=self.tmp).splitlines()
        self.assertEqual(printed[0], ARGS.version)
        self.assertTrue(printed[1].startswith(self.prefix), printed[1])
        self.assertIn(os.path.realpath(self.libdir), printed[2])
        built = self.denoise(self.build_tool, "python_build.exr", "--cnn")
        names, values = pixels(built)
        installed_names, installed_values = pixels(out)
        for c in ("ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B"):
            np.testing.assert_array_equal(installed_values[:, :, installed_names.index(c)],
                                          values[:, :, names.index(c)])

    def test_a_cmake_project_finds_and_uses_it(self):
        build = os.path.join(self.tmp, "consumer-build")
        run(["cmake", "-S", os.path.join(HERE, "consumer"), "-B", build,
             "-DCMAKE_PREFIX_PATH=" + self.prefix, "-DCMAKE_BUILD_TYPE=Release"],
            env=clean_env())
        run(["cmake", "--build", build], env=clean_env())
        printed = run([os.path.join(build, "consumer"), RENDER, REFERENCE], env=clean_env())
        self.assertIn("mcdenoise " + ARGS.version, printed)

    def test_pkg_config_builds_it(self):
        env = clean_env(PKG_CONFIG_PATH=os.path.join(self.libdir, "pkgconfig"))
        flags = run(["pkg-config", "--cflags", "--libs", "mcdenoise"], env=env).split()
        self.assertEqual(run(["pkg-config", "--modversion", "mcdenoise"], env=env).strip(),
                         ARGS.version)
        exe = os.path.join(self.tmp, "consumer-pc")
        run(["g++", "-std=c++17", "-O1", os.path.join(HERE, "consumer", "main.cpp"), "-o", exe,
             "-Wl,-rpath," + self.libdir] + flags, env=env)
        printed = run([exe, RENDER, REFERENCE], env=clean_env())
        self.assertIn("mcdenoise " + ARGS.version, printed)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--build", required=True)
    parser.add_argument("--version", required=True)
    parser.add_argument("--plugin-dir", required=True, help="the build tree's plugin folder")
    ARGS, rest = parser.parse_known_args()
    ARGS.build = os.path.abspath(ARGS.build)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
