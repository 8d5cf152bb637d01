"""The package's layers: which part of tapm_opt may import which (data only, no imports).

Imports point one way, from a layer to the layers it builds on (and everything below them):

====================  =========================================================  ===================
layer                 modules                                                    builds on
====================  =========================================================  ===================
``base``              every top-level module (``errors``, ``geometry``,          (nothing)
                      ``interfaces``, ``results``, ``standards``, ``_io``,
                      ``_checks``, ...) but ``__init__`` and ``__main__``
``config``            ``config/``: scenario schema, loading, validation          base
``package``           ``tapm_opt/__init__.py``: re-exports config and errors     config
``models``            ``models/``: control-design models                         package
``plant``             ``plant/``: the numpy truth                                models
``estimation``        ``estimation/``: observers, detection, reliability, SLAM   models
``control``           ``control/``: controllers, allocation, setpoints,          estimation
                      supervisor, winch
``design``            ``design/``: gain tables, capability, references           control, plant
``studies``           ``studies/``: cases, runners, KPIs, stores                 design
``report``            ``report/``: figures and documents                         studies
``cli``               ``cli/``: the ``tapm`` command                             report
``main``              ``__main__.py``                                            cli
====================  =========================================================  ===================

``plant``, ``estimation`` and ``control`` are siblings over ``models``, with one direction
between two of them: a controller uses the estimators' public signals and filters, so
``control`` may import ``estimation``, never the reverse. Neither imports ``plant`` (a
controller and an estimator see measurements, never the plant's internals), and ``plant``
imports neither (the truth does not depend on what estimates it). Design-time work that needs
the plant's models (references, tables) is in ``design`` and is passed in to run-time objects.

``tests/test_import_graph.py`` checks every import of the package against :data:`LAYERS`
(module-level and lazy imports inside functions alike), and that there are no import cycles and
no private name (``_x``) imported from another package. A module that fits no layer fails the
test: place a new subpackage here (a new top-level module is ``base``, so it may import only
other top-level helpers).
"""

from __future__ import annotations

__all__ = ["LAYERS", "layer_of", "may_import"]

#: ``(layer, modules, builds_on)``, from the bottom up. ``modules`` are module or package
#: names; a package name covers its submodules, except ``"tapm_opt"`` itself, which names only
#: the package's ``__init__``; ``"tapm_opt.*"`` is any top-level module not named elsewhere. ``builds_on`` are the layers imported directly; what they build on
#: may be imported too.
LAYERS: tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...] = (
    ("base", ("tapm_opt.*",), ()),
    ("config", ("tapm_opt.config",), ("base",)),
    ("package", ("tapm_opt",), ("config",)),
    ("models", ("tapm_opt.models",), ("package",)),
    ("plant", ("tapm_opt.plant",), ("models",)),
    ("estimation", ("tapm_opt.estimation",), ("models",)),
    ("control", ("tapm_opt.control",), ("estimation",)),
    ("design", ("tapm_opt.design",), ("control", "plant")),
    ("studies", ("tapm_opt.studies",), ("design",)),
    ("report", ("tapm_opt.report",), ("studies",)),
    ("cli", ("tapm_opt.cli",), ("report",)),
    ("main", ("tapm_opt.__main__",), ("cli",)),
)


def layer_of(module: str) -> str | None:
    """The layer of a module name (``"tapm_opt.control.pid"`` -> ``"control"``); None when no
    layer holds it. Static: a new subpackage gets no layer until it is added to :data:`LAYERS`,
    whereas a top-level module (``tapm_opt.x``) is ``base`` unless named elsewhere."""
    best, best_len = None, -1
    for name, modules, _ in LAYERS:
        for m in modules:
            if m == "tapm_opt.*":
                continue
            hit = module == m or (m != "tapm_opt" and module.startswith(m + "."))
            if hit and len(m) > best_len:
                best, best_len = name, len(m)
    if best is None and module.count(".") == 1 and module.startswith("tapm_opt."):
        best = next(name for name, modules, _ in LAYERS if "tapm_opt.*" in modules)
    return best


def _below(layer: str) -> frozenset[str]:
    builds = {name: deps for name, _, deps in LAYERS}
    seen: set[str] = set()
    todo = list(builds[layer])
    while todo:
        lay = todo.pop()
        if lay not in seen:
            seen.add(lay)
            todo.extend(builds[lay])
    return frozenset(seen)


def may_import(importer: str, imported: str) -> bool:
    """Whether a module of layer ``importer`` may import one of layer ``imported``: the same
    layer, or one it builds on directly or through others."""
    return importer == imported or imported in _below(importer)
