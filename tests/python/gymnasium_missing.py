"""What a Python test does where Gymnasium cannot be imported: a user's machine without PyPI skips
it with one line (scripts/setup.sh said so when it could not install Gymnasium); CI (CI=true),
which must run every test, fails it."""
import os

import pytest


def skip_or_fail(error, module=False):
    reason = (f"Gymnasium cannot be imported ({error}); ./scripts/setup.sh installs it from PyPI into .venv "
              "(python/requirements.txt)")
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason}, and CI runs every test", pytrace=False)
    pytest.skip(reason, allow_module_level=module)
