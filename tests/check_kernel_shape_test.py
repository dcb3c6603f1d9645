#!/usr/bin/env python3
"""Self-test of tests/check_kernel_shape.py: each check passes on a small clean tree and fails on a broken copy.

Usage: python3 tests/check_kernel_shape_test.py [-v]   (needs universal-ctags, like the checker)
"""

import contextlib
import io
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import unittest
from unittest import mock

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import check_kernel_shape as shape  # noqa: E402  (found next to this file)

SCRIPT = os.path.join(HERE, "check_kernel_shape.py")

# A tree shaped like the target layout; every check passes on it.
CLEAN_TREE = {
    "kernel/CMakeLists.txt": """
        # Plugins (rcand_nav) are never linked here; plugins/ is the kernel's own plugin host folder.
        add_library(rcand_kernel STATIC kernel.cpp plugins/plugin_host.cpp registry/standard_capabilities.cpp)
        target_link_libraries(rcand_kernel PUBLIC rcand_base)
        """,
    "kernel/kernel.hpp": """
        #pragma once
        #include "libs/base/log.hpp"
        namespace rcand::kernel {
        class Kernel {
         public:
          int start() { return 0; }
        };
        }  // namespace rcand::kernel
        """,
    "kernel/kernel.cpp": """
        #include "kernel/kernel.hpp"
        #include "kernel/plugins/plugin_host.hpp"
        #include <rcand/sdk/plugin.hpp>
        #include <string>
        // A comment naming "nav" and plugins/nav/nav.hpp is no code.
        /* Neither is "teleop" here. */
        namespace rcand::kernel {
        const char* route() { return "/api/nav/waypoint"; }
        const char* other() { return "navigation"; }
        }  // namespace rcand::kernel
        """,
    "kernel/plugins/plugin_host.hpp": """
        #pragma once
        #include "plugin_record.hpp"
        """,
    "kernel/plugins/plugin_record.hpp": "#pragma once\nstruct PluginRecord {};\n",
    "kernel/plugins/plugin_host.cpp": """
        #include "kernel/plugins/plugin_host.hpp"
        #include "plugins/plugin_record.hpp"
        int host() { return 1; }
        """,
    "kernel/registry/standard_capabilities.cpp": """
        #include <array>
        const std::array<const char*, 5> kStandard{"nav", "teleop", "vision", "chat", "arm"};
        """,
    "libs/base/log.hpp": "#pragma once\nvoid log();\n",
    "libs/base/log.cpp": '#include "libs/base/log.hpp"\n#include "libs/base/other.hpp"\nvoid log() {}\n',
    "libs/base/other.hpp": "#pragma once\n",
    "sdk/include/rcand/sdk/plugin.hpp": "#pragma once\n",
    "services/r2r/node.hpp": '#pragma once\n#include "kernel/kernel.hpp"\n',
    "plugins/CMakeLists.txt": "add_subdirectory(nav)\n",
    "plugins/nav/CMakeLists.txt": """
        rcand_add_plugin(rcand_nav MANIFEST nav.json SOURCES nav.cpp)
        add_library(rcand_nav_plan STATIC waypoint_plan.cpp)
        add_library(${name}_extra STATIC x.cpp)  # a computed name is not a target we can know
        """,
    "plugins/nav/nav.hpp": "#pragma once\n",
    "plugins/nav/waypoint_plan.hpp": "#pragma once\n",
    "rcanctl/main.cpp": '#include "kernel/kernel.hpp"\n#include "plugins/nav/nav.hpp"\nint main() {}\n',
}


def function_source(name, lines):
    """A function spanning exactly `lines` lines, its signature on the first."""
    body = "".join(f"  v += {k};\n" for k in range(lines - 4))
    return f"int {name}() {{\n  int v = 0;\n{body}  return v;\n}}\n"


class TreeCase(unittest.TestCase):
    def setUp(self):
        self.root = tempfile.mkdtemp(prefix="kernel-shape-")
        self.addCleanup(shutil.rmtree, self.root)
        for rel, text in CLEAN_TREE.items():
            self.write(rel, textwrap.dedent(text).lstrip("\n"))

    def write(self, rel, text):
        path = os.path.join(self.root, rel)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)

    def remove(self, rel):
        os.remove(os.path.join(self.root, rel))

    def run_check(self):
        """(exit code, report) of the checker on this tree, in-process so tests can patch its constants."""
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = shape.main(["check_kernel_shape.py", self.root])
        return code, out.getvalue()

    def assert_check(self, letter, passes, *expected):
        code, report = self.run_check()
        status = "PASS" if passes else "FAIL"
        self.assertIn(f"[{status}] {letter})", report, report)
        for text in expected:
            self.assertIn(text, report, report)
        return code, report


class CleanTreeTest(TreeCase):
    def test_all_checks_pass(self):
        code, report = self.run_check()
        self.assertEqual(code, 0, report)
        self.assertNotIn("[FAIL]", report)

    def test_command_line_exit_codes(self):
        ok = subprocess.run([sys.executable, SCRIPT, self.root], capture_output=True, text=True, timeout=30)
        self.assertEqual(ok.returncode, 0, ok.stdout + ok.stderr)
        self.write("kernel/bad.cpp", 'const char* c = "arm";\n')
        bad = subprocess.run([sys.executable, SCRIPT], cwd=self.root, capture_output=True, text=True, timeout=30)
        self.assertEqual(bad.returncode, 1, bad.stdout + bad.stderr)
        missing = subprocess.run([sys.executable, SCRIPT, os.path.join(self.root, "nowhere")],
                                 capture_output=True, text=True, timeout=30)
        self.assertEqual(missing.returncode, 2)


class SizeTest(TreeCase):
    def kernel_with(self, code_lines):
        # Blank lines, comments and a commented-out block around the code must not count.
        body = "".join(f"int v{k} = {k};  // value\n\n// note\n" for k in range(code_lines))
        self.write("kernel/big.cpp", "/* header\n   comment */\n" + body)

    def counted(self):
        scans = {p: shape.scan_cxx(shape.read(self.root, p))
                 for p in shape.files_under(self.root, "kernel", shape.COUNTED_SUFFIXES)}
        return sum(len(s.code_lines) for s in scans.values())

    def test_passes_at_the_limit(self):
        base = self.counted()
        self.kernel_with(shape.KERNEL_LINE_LIMIT - base)
        self.assert_check("a", True, f"{shape.KERNEL_LINE_LIMIT} code lines", "kernel/big.cpp")

    def test_fails_one_over(self):
        base = self.counted()
        self.kernel_with(shape.KERNEL_LINE_LIMIT - base + 1)
        code, _ = self.assert_check("a", False, "1 over")
        self.assertEqual(code, 1)

    def test_other_suffixes_and_trees_do_not_count(self):
        self.write("kernel/notes.md", "x\n" * 10000)
        self.write("libs/base/huge.cpp", "int x;\n" * 10000)
        self.assert_check("a", True)

    def test_scanner(self):
        text = textwrap.dedent(r'''
            // comment "nav"
            int a = 1'000'000;  /* "teleop" */ const char* s = "x // not a comment";
            /* block
               "vision" */
            char q = '"'; const char* r = R"sep(
            "chat" )"
            )sep";
            auto w = u8"arm"; auto e = "a\"b";
            #include "libs/x.hpp"  // "arm"

            const char* t = "nav"sv;
            ''').lstrip("\n")
        scan = shape.scan_cxx(text)
        self.assertEqual(sorted(scan.code_lines), [2, 5, 6, 7, 8, 9, 11])
        bodies = [b for _, b in scan.literals]
        self.assertEqual(bodies, ["x // not a comment", '\n"chat" )"\n', "arm", 'a\\"b', "nav"])
        self.assertEqual(scan.includes, [(9, True, "libs/x.hpp")])


class FunctionLengthTest(TreeCase):
    def test_sixty_lines_pass(self):
        self.write("kernel/work.cpp", function_source("work", shape.FUNCTION_LINE_LIMIT))
        self.assert_check("b", True)

    def test_sixty_one_lines_fail_with_location(self):
        self.write("kernel/work.cpp", "// leading comment\n" + function_source("work", 61))
        self.assert_check("b", False, "61 lines  kernel/work.cpp:2  work")

    def test_member_function_in_a_header(self):
        source = function_source("run", 70).replace("int run()", "  int run()")
        self.write("kernel/task.hpp", "#pragma once\nclass Task {\n public:\n" + source + "};\n")
        self.assert_check("b", False, "kernel/task.hpp:4  Task::run")

    def test_long_lambda_is_named_by_its_function(self):
        body = "".join(f"    v += {k};\n" for k in range(70))
        self.write("kernel/make.cpp", "#include <functional>\nstd::function<int()> make() {\n"
                   "  return [] {\n    int v = 0;\n" + body + "    return v;\n  };\n}\n")
        self.assert_check("b", False, "kernel/make.cpp:3  lambda in make")

    def test_allowlist(self):
        self.write("kernel/table.cpp", function_source("table", 80))
        with mock.patch.dict(shape.LONG_FUNCTION_ALLOWLIST, {"kernel/table.cpp:table": "a data table"}):
            self.assert_check("b", True, "(1 more allowlisted)")

    def test_stale_allowlist_entry_is_noted(self):
        with mock.patch.dict(shape.LONG_FUNCTION_ALLOWLIST, {"kernel/gone.cpp:gone": "was a table"}):
            self.assert_check("b", True, "allowlist entry no longer needed: kernel/gone.cpp:gone")


class LayeringTest(TreeCase):
    def test_kernel_includes_a_service(self):
        self.write("services/r2r/r2r_service.hpp", "#pragma once\n")
        self.write("kernel/glue.cpp", '#include "services/r2r/r2r_service.hpp"\n')
        self.assert_check("c", False, 'kernel/glue.cpp:1: includes "services/r2r/r2r_service.hpp" from services/')

    def test_kernel_includes_a_plugin(self):
        self.write("kernel/glue.cpp", '\n#include "plugins/nav/nav.hpp"\n')
        self.assert_check("c", False, "kernel/glue.cpp:2:")

    def test_kernel_includes_rcanctl_by_angle_and_not_yet_existing_path(self):
        self.write("kernel/glue.hpp", "#include <rcand/rcanctl/commands.hpp>\n")
        self.assert_check("c", False, "kernel/glue.hpp:1: includes <rcand/rcanctl/commands.hpp> from rcanctl/")

    def test_kernel_finds_a_plugin_header_through_an_include_path(self):
        self.write("kernel/cost.cpp", '#include "waypoint_plan.hpp"\n')
        self.assert_check("c", False, 'kernel/cost.cpp:1: includes "waypoint_plan.hpp" from plugins/')

    def test_commented_include_is_ignored(self):
        self.write("kernel/glue.cpp", '// #include "plugins/nav/nav.hpp"\n/*\n#include "plugins/nav/nav.hpp"\n*/\n')
        self.assert_check("c", True)

    def test_libs_include_the_kernel(self):
        self.write("libs/base/log.cpp", '#include "kernel/kernel.hpp"\n')
        self.assert_check("c", False, 'libs/base/log.cpp:1: includes "kernel/kernel.hpp" from kernel/')

    def test_libs_include_old_style_kernel_header(self):
        self.write("kernel/include/rcand/kernel/core/api.hpp", "#pragma once\n")
        self.write("libs/base/log.cpp", "#include <rcand/kernel/core/api.hpp>\n")
        self.assert_check("c", False, "libs/base/log.cpp:1: includes <rcand/kernel/core/api.hpp> from kernel/")

    def test_libs_include_a_service(self):
        self.write("libs/base/log.hpp", '#include "services/r2r/node.hpp"\n')
        self.assert_check("c", False, "libs/base/log.hpp:1:")

    def test_kernel_cmake_links_a_plugin_target(self):
        self.write("kernel/CMakeLists.txt", "add_library(k STATIC kernel.cpp)\n"
                   "target_link_libraries(k PRIVATE rcand_nav_plan)\n")
        self.assert_check("c", False, "kernel/CMakeLists.txt:2: names the plugin target rcand_nav_plan "
                          "(defined at plugins/nav/CMakeLists.txt:2)")

    def test_kernel_cmake_names_a_plugin_source(self):
        self.write("kernel/sub/CMakeLists.txt", "target_sources(k PRIVATE\n"
                   "  ${PROJECT_SOURCE_DIR}/plugins/nav/nav.cpp ../../plugins/nav/x.cpp)\n")
        self.assert_check("c", False, "kernel/sub/CMakeLists.txt:2: names the plugin path "
                          "${PROJECT_SOURCE_DIR}/plugins/nav/nav.cpp",
                          "kernel/sub/CMakeLists.txt:2: names the plugin path ../../plugins/nav/x.cpp")

    def test_kernel_cmake_generator_expression_with_plugin_target(self):
        self.write("kernel/CMakeLists.txt", 'set(p "$<TARGET_FILE:rcand_nav>")\n')
        self.assert_check("c", False, "names the plugin target rcand_nav ")


class CapabilityNameTest(TreeCase):
    def test_name_outside_the_table(self):
        self.write("kernel/api/api.cpp", 'bool nav(const std::string& n) {\n  return n == "nav";\n}\n')
        self.assert_check("d", False, 'kernel/api/api.cpp:2: "nav"')

    def test_every_standard_name_is_caught(self):
        self.write("kernel/api/api.cpp", "".join(f'auto c{k} = "{n}";\n'
                                                 for k, n in enumerate(shape.STANDARD_CAPABILITIES)))
        _, report = self.assert_check("d", False)
        for k, name in enumerate(shape.STANDARD_CAPABILITIES):
            self.assertIn(f'kernel/api/api.cpp:{k + 1}: "{name}"', report)

    def test_fallback_table_file(self):
        self.remove("kernel/registry/standard_capabilities.cpp")
        self.write("kernel/caps/standard_capability_table.hpp", 'inline const char* kNav = "nav";\n')
        self.assert_check("d", True, "kernel/caps/standard_capability_table.hpp")

    def test_fallback_allows_one_file_only(self):
        self.remove("kernel/registry/standard_capabilities.cpp")
        self.write("kernel/caps/standard_capabilities.hpp", 'inline const char* kNav = "nav";\n')
        self.write("kernel/caps/standard_capabilities_more.hpp", 'inline const char* kArm = "arm";\n')
        self.assert_check("d", False, "expected one")

    def test_fallback_ignored_while_the_named_table_exists(self):
        self.write("kernel/caps/standard_capabilities.hpp", 'inline const char* kNav = "nav";\n')
        self.assert_check("d", False, 'kernel/caps/standard_capabilities.hpp:1: "nav"')

    def test_other_trees_may_name_capabilities(self):
        self.write("services/r2r/node.cpp", 'auto c = "nav";\n')
        self.write("plugins/nav/nav.cpp", 'auto c = "nav";\n')
        self.assert_check("d", True)


if __name__ == "__main__":
    unittest.main()
