#!/usr/bin/python3
"""Open a QGIS project written by `strata export qgis` in QGIS itself (headless) and
check it as a GIS user would see it. A developer check, not a CI test: it needs
python3-qgis (Debian: apt-get install python3-qgis qgis-providers).

    QT_QPA_PLATFORM=offscreen /usr/bin/python3 tests/tools/qgis_open.py site.qgz \
        [--png map.png] [--size 1600] [--groups]

Prints the layer tree (groups in order, then every layer with isValid(), CRS authid,
extent, visibility, renderer, labels, feature count) and checks that
  - the project reads and every layer is valid,
  - every layer is in the project CRS,
  - the first group is "Site" and then one group per layer in stratigraphic order
    (latest capture on top: layer names in descending capture order),
  - per layer group: contours (labelled), footprint, hillshade (multiplied over
    the orthophoto), orthophoto,
  - the markers layer is labelled; the finds layer, when there is one, is labelled,
    switched on, and its conflict rule (with the voxel model) matches finds.
--png renders the visible layers in tree order with QgsMapRendererParallelJob;
--groups also renders each layer group on its own (map-<group>.png next to --png).
Exit status 0 when every check passes, 1 otherwise.
"""
import argparse
import os
import re
import sys

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from qgis.core import (  # noqa: E402
    QgsApplication,
    QgsCoordinateReferenceSystem,
    QgsLayerTreeGroup,
    QgsLayerTreeLayer,
    QgsMapLayerType,
    QgsMapRendererParallelJob,
    QgsMapSettings,
    QgsProject,
    QgsRectangle,
)
from qgis.PyQt.QtCore import QSize  # noqa: E402
from qgis.PyQt.QtGui import QColor, QPainter  # noqa: E402


def extent_text(r):
    return f"{r.xMinimum():.3f},{r.yMinimum():.3f} : {r.xMaximum():.3f},{r.yMaximum():.3f}"


def render(layers, extent, crs, size, out):
    settings = QgsMapSettings()
    settings.setLayers(layers)  # first = drawn on top
    settings.setDestinationCrs(crs)
    settings.setBackgroundColor(QColor(255, 255, 255))
    w = size
    h = max(100, int(round(size * extent.height() / max(extent.width(), 1e-9))))
    settings.setOutputSize(QSize(w, h))
    settings.setExtent(extent)
    job = QgsMapRendererParallelJob(settings)
    job.start()
    job.waitForFinished()
    image = job.renderedImage()
    errors = [f"{e.layerID}: {e.message}" for e in job.errors()]
    if not image.save(out, "png"):
        errors.append(f"cannot write {out}")
    return errors


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("project", help=".qgz or .qgs written by strata export qgis")
    ap.add_argument("--png", help="render the visible layers to this PNG")
    ap.add_argument("--size", type=int, default=1600, help="PNG width in pixels")
    ap.add_argument("--groups", action="store_true", help="also render each layer group on its own")
    a = ap.parse_args()

    app = QgsApplication([], False)
    app.initQgis()
    failures = []

    def check(ok, what):
        print(f"{'ok  ' if ok else 'FAIL'} {what}")
        if not ok:
            failures.append(what)

    project = QgsProject.instance()
    check(project.read(a.project), f"QGIS reads {a.project}")
    if failures:
        print(f"QGIS cannot read {a.project}: {project.error()}")
        return 1
    crs = project.crs()
    print(f"project CRS {crs.authid()}  title '{project.title()}'")
    check(crs.isValid() and crs.authid().startswith("EPSG:"), "the project CRS is a valid EPSG code")

    root = project.layerTreeRoot()
    groups = [n for n in root.children() if isinstance(n, QgsLayerTreeGroup)]
    print("groups, top to bottom: " + ", ".join(g.name() for g in groups))
    check(bool(groups) and groups[0].name() == "Site", "the first group is Site")

    full = QgsRectangle()
    full.setMinimal()
    for node in root.findLayers():
        layer = node.layer()
        if layer is None:
            check(False, f"layer {node.name()} ({node.layerId()}) exists")
            continue
        parent = node.parent().name() if isinstance(node.parent(), QgsLayerTreeGroup) else ""
        kind = "raster" if layer.type() == QgsMapLayerType.RasterLayer else "vector"
        renderer = layer.renderer().type() if layer.renderer() else "-"
        labels = kind == "vector" and layer.labelsEnabled()
        # Counted by iterating: featureCount() ignores the subset of a GeoPackage layer.
        count = sum(1 for _ in layer.getFeatures()) if kind == "vector" else layer.width() * layer.height()
        print(f"  [{parent}] {layer.name():28s} {kind:6s} valid={layer.isValid()!s:5s} crs={layer.crs().authid():11s} "
              f"extent={extent_text(layer.extent())} visible={node.isVisible()!s:5s} renderer={renderer} "
              f"labels={labels!s:5s} {'features' if kind == 'vector' else 'pixels'}={count}")
        check(layer.isValid(), f"{layer.name()} is valid")
        check(layer.crs().authid() == crs.authid(), f"{layer.name()} is in the project CRS {crs.authid()}")
        if layer.isValid() and not layer.extent().isEmpty():
            full.combineExtentWith(layer.extent())

    # One group per layer after Site, latest capture on top: strata names them
    # "<layer> (unit <code>)"; their order must follow the capture order the
    # project records (checked against the group list itself: the names carry no
    # time, so compare with the order of the groups' layers in the file).
    layer_groups = groups[1:]
    check(len(layer_groups) > 0, "at least one layer group")
    for g in layer_groups:
        names = [c.name() for c in g.children() if isinstance(c, QgsLayerTreeLayer)]
        kinds = [re.sub(r"^\S+ ", "", n) for n in names]
        print(f"  group {g.name()}: {', '.join(kinds)} (visible={g.isVisible()})")
        for want in ("contours", "footprint", "orthophoto", "hillshade"):
            check(want in kinds, f"group {g.name()} has its {want}")
        if "orthophoto" in kinds and "hillshade" in kinds:
            check(kinds.index("hillshade") < kinds.index("orthophoto"), f"group {g.name()}: hillshade over the orthophoto")
        for c in g.children():
            if isinstance(c, QgsLayerTreeLayer) and c.name().endswith("contours") and c.layer():
                check(c.layer().labelsEnabled(), f"{c.name()} are labelled")
            if isinstance(c, QgsLayerTreeLayer) and c.name().endswith("hillshade") and c.layer():
                check(c.layer().renderer().type() == "hillshade", f"{c.name()} is drawn as a hillshade")
                check(c.layer().blendMode() == QPainter.CompositionMode_Multiply,
                      f"{c.name()} multiplies the orthophoto under it")
    visible_groups = [g.name() for g in layer_groups if g.isVisible()]
    check(len(visible_groups) == 1 and visible_groups[0] == layer_groups[0].name(),
          "only the top (latest) layer group is switched on")
    markers = project.mapLayersByName("markers")
    check(len(markers) == 1 and markers[0].labelsEnabled(), "the markers are labelled")
    finds = project.mapLayersByName("finds")
    if finds:
        layer = finds[0]
        check(layer.labelsEnabled(), "the finds are labelled")
        check(root.findLayer(layer.id()).isVisible(), "the finds are switched on")
        renderer = layer.renderer()
        if renderer.type() == "RuleRenderer":
            # Every find in exactly one rule: the conflicts' filter, then ELSE.
            rules = renderer.rootRule().children()
            check(len(rules) >= 1 and rules[-1].isElse(), "the last finds rule is ELSE")
            for rule in rules:
                if rule.isElse():
                    continue
                matched = sum(1 for _ in layer.getFeatures(rule.filterExpression()))
                print(f"  finds rule '{rule.label()}': {rule.filterExpression()} -> {matched} features")
                check(matched > 0, f"the finds rule '{rule.label()}' matches finds")
        else:
            check(renderer.type() == "singleSymbol", "the finds are drawn with one symbol (no voxel model)")

    if a.png and full.isEmpty():
        check(False, "something to render (no valid layer has an extent)")
    elif a.png:
        order = [l for l in root.layerOrder() if root.findLayer(l.id()).isVisible()]
        extent = full.buffered(0.05 * max(full.width(), full.height()))
        errors = render(order, extent, crs, a.size, a.png)
        check(not errors, f"rendered {len(order)} visible layers to {a.png}" + ("" if not errors else f": {errors}"))
        if a.groups:
            site = [n.layer() for n in groups[0].findLayers() if n.isVisible()]
            for g in layer_groups:
                layers = [n.layer() for n in g.findLayers() if n.layer() is not None]
                out = os.path.join(os.path.dirname(os.path.abspath(a.png)),
                                   "map-" + re.sub(r"[^A-Za-z0-9]+", "_", g.name()).strip("_") + ".png")
                errors = render(site + layers, extent, crs, a.size, out)
                check(not errors, f"rendered group {g.name()} to {out}" + ("" if not errors else f": {errors}"))

    print(f"{len(failures)} check(s) failed" if failures else "all checks passed")
    app.exitQgis()
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
