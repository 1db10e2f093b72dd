"""Every name a package re-exports lazily resolves to its module's object."""

import importlib
import pkgutil

import pytest

import labrig

PACKAGES = sorted(
    {"labrig", "labrig.drivers", "labrig.sim"}
    | {m.name for m in pkgutil.walk_packages(labrig.__path__, "labrig.") if m.ispkg}
)


@pytest.mark.parametrize("package_name", PACKAGES)
def test_every_exported_name_resolves(package_name):
    package = importlib.import_module(package_name)
    for name in dir(package):
        if name.startswith("_") or name in vars(package):
            continue  # defined in the package itself: nothing to resolve
        value = getattr(package, name)
        owner = getattr(value, "__module__", package_name + ".")
        assert owner.startswith(package_name + "."), f"{package_name}.{name} is {owner}'s"


def test_an_unknown_name_is_an_attribute_error():
    import labrig.rig

    with pytest.raises(AttributeError, match=r"'labrig\.rig' has no attribute 'no_such_name'"):
        labrig.rig.no_such_name  # noqa: B018
