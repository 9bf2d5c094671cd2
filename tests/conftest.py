import pytest

from redundancy import load_robot


@pytest.fixture(scope="session")
def crane():
    return load_robot("hiab031")
