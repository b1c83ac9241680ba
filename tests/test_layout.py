import importlib

import pytest


@pytest.mark.parametrize(
    "name", ["gyrocal.models", "gyrocal.instruments", "gyrocal.orchestrator", "gyrocal.reports"]
)
def test_product_folders_install_under_the_gyrocal_namespace(name):
    module = importlib.import_module(name)
    assert module.__name__ == name
