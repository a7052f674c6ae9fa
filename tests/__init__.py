import pytest

# the shared checks of the builders' tests: their failed asserts show the values, as in a test
pytest.register_assert_rewrite("tests.references.engines.system_builders")
