# The module under test is the build tree's (PYTHONPATH set by CTest, tests/python/CMakeLists.txt); the CLI
# beside it gives the messages the module must repeat and the synthetic trials.
import os
import subprocess

import pytest


@pytest.fixture(scope="session")
def cli():
    path = os.environ.get("TIRSTRAIN_CLI")
    if not path:
        pytest.fail("TIRSTRAIN_CLI is not set (run through ctest)")

    def run(*args):
        return subprocess.run([path, *map(str, args)], capture_output=True, text=True)

    return run


def cli_error(result):
    """The message the CLI printed after 'tirstrain: error: '."""
    assert result.returncode == 1, result.stderr
    prefix = "tirstrain: error: "
    line = next(l for l in result.stderr.splitlines() if l.startswith(prefix))
    return line[len(prefix):]
