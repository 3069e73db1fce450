"""The photos of ``fetch_photos.py``: every package used and each file reviewed in it.

Kept apart from the fetching code so the review (one word per file: its subject, or
why it was left out) reads as a list. See docs/learned.md, "Training photos".
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import PurePosixPath

_RESOLUTION = re.compile(r"\d+x\d+")


def _each(reason: str, names: str) -> dict[str, str]:
    return dict.fromkeys(names.split(), reason)


def plain_stem(rel: PurePosixPath) -> str:
    """The file's stem; a stem like ``2560x1600`` is replaced by its wallpaper's folder.

    >>> plain_stem(PurePosixPath("usr/share/wallpapers/Path/contents/images/2560x1600.jpg"))
    'Path'
    """
    if _RESOLUTION.fullmatch(rel.stem):
        return next(p for p in reversed(rel.parts[:-1]) if p not in ("contents", "images"))
    return rel.stem


def folder_stem(rel: PurePosixPath) -> str:
    """``<folder>-<stem>``: for packages whose folders reuse file names."""
    return f"{rel.parent.name}-{rel.stem}"


def resource_stem(rel: PurePosixPath) -> str:
    """GCompris: the activity and the path inside its resources (``erase-alpaca``)."""
    parts = rel.with_suffix("").parts
    parts = parts[parts.index("src") + 1:] if "src" in parts else parts
    return "-".join(p for p in parts if p not in ("activities", "resource"))


@dataclass(frozen=True)
class Source:
    """One package's photos: where they are and which of them to keep."""

    package: str
    """Debian package, or the Python distribution when ``python`` is set."""
    globs: tuple[str, ...]
    """Candidate files, relative to the unpacked package (or the Python package)."""
    keep: dict[str, str]
    """Stem -> one-word subject: the files reviewed as real photographs."""
    drop: dict[str, str] = field(default_factory=dict)
    """Stem pattern (fnmatch) -> one-word reason: files reviewed and left out."""
    licences: dict[str, tuple[str, str]] = field(default_factory=dict)
    """Stem -> (licence, where it is stated), more precise than the copyright file."""
    freeform: tuple[str, str] | None = None
    """(licence, phrase) for a copyright file that is not DEP-5: the phrase must occur."""
    heldout: bool = False
    """Every photo is held out (photo3d's evaluation photos)."""
    python: str | None = None
    """Import name: the photos ship inside this installed Python package."""
    rcc: str | None = None
    """Glob of Qt resource files whose images are unpacked first (under ``.rcc/``)."""
    stem: Callable[[PurePosixPath], str] = plain_stem
    """The stable stem of a candidate (the ``<stem>`` of ``<package>--<stem>.png``)."""
    largest_only: bool = False
    """A folder holds one photo at several sizes: only its largest file is a candidate."""
    turns: dict[str, int] = field(default_factory=dict)
    """Stem -> clockwise degrees to turn it upright, beyond its EXIF orientation."""


_GC_ERASE_CREDITS = {  # GCompris ActivityInfo.qml "credit" (Wikimedia Commons)
    "CC-BY-SA-4.0": "alpaca butterfly calf camels caterpillar cheetah dolphin flying_fox goat "
                    "gorilla gosling heron horse long_nosed_monkey macaque meerkats "
                    "northern_harrier nubian_ibex penguin rhinoceros spoonbills squirrel swans "
                    "toucan",
    "CC-BY-2.0": "bee kitten", "CC-BY-3.0": "chamaeleon gibbon"}
_GC_DETAILS_CREDITS = {
    "CC-BY-SA-3.0": "Chenonceau EgeskovSlotSpejling FanoeWindmill NDP Nagoya Neuschwanstein "
                    "OperaSidney TajMahal",
    "CC-BY-3.0": "EilanDonanCastle", "CC-BY-SA-2.0": "GizahPyramids",
    "CC-BY-SA-4.0": "TowerBridgeLondon"}
_GC_LICENCES = {
    **{f"erase-{n}": (lic, "erase/ActivityInfo.qml credit")
       for lic, names in _GC_ERASE_CREDITS.items() for n in names.split()},
    **{f"details-image-{n}_background": (lic, "details/ActivityInfo.qml credit")
       for lic, names in _GC_DETAILS_CREDITS.items() for n in names.split()},
    **{f"explore_monuments-wonders-{n}": ("CC-BY-SA-4.0", "explore_monuments/ActivityInfo.qml")
       for n in ("chichenItza", "christTheRedeemer", "tajMahal")}}
_GC_MONUMENTS = (
    "egypt: bentPyramid greatPyramidOfGiza meidumPyramid redPyramid; france: arlesAmphitheater "
    "chateaudeChambord chateaudeChenonceau citedeCarcassonne eiffelTower montStMichel "
    "palaisdesPapes pontduGard reimsCathedral rocamadour; germany: aulaPalatina berlinCathedral "
    "brandenburgGate neuschwansteinCastle schwerinPalace trierImperialBaths wormsCathedral; "
    "india: ajantaCave charminar gatewayofIndia goldenTemple greatStupa hawaMahal "
    "konarkSunTemple mysorePalace qutubMinar rangGhar victoriaMemorial; usa: cabrillo "
    "canyondeChelly castillodeSanMarcos castleClinton fortSumter georgeWashingtonBirthplace "
    "lincolnMemorial mountRushmore navajo statueofLiberty; wonders: chichenItza "
    "christTheRedeemer colosseum greatWallofChina machuPicchu petra tajMahal")
_GC_KEEP = {
    **{f"explore_monuments-{region.strip()}-{n}": "monument"
       for region, names in (g.split(":") for g in _GC_MONUMENTS.split(";"))
       for n in names.split()},
    **{f"erase-{n}": "animal" for n in _GC_ERASE_CREDITS["CC-BY-SA-4.0"].split()
       + "bee kitten chamaeleon gibbon crab giraffe kingfisher pika red_panda".split()},
    **{f"details-image-{n}_background": "monument" for names in _GC_DETAILS_CREDITS.values()
       for n in names.split()},
    **{f"explore_farm_animals-animals-{n}": "animal"
       for n in "cat chicken cow dog duck horse owl pig sheep".split()},
    **{f"explore_world_animals-animals-{n}": "animal"
       for n in ("bison chameleon crocodile dragon giraffe hedgehog jaguar kangaroo koala lemur "
                 "moose narwhal panda polar_bear scarlet_macaw").split()},
    **{f"explore_world_music-music-{n}": "people"
       for n in "africa america australia ireland italy japan mexico middleeast orchestra".split()},
    **{f"clickgame-sea{i}": "underwater" for i in range(1, 7)},
    **{f"categorization-images-{n}": "object"
       for n in ("alphabets-alphabets numbers-numbers others-baseball others-volleyball "
                 "tools-spray").split()},
    "categorization-images-monuments-victoriaMemorial": "monument",
    "categorization-images-renewable-windmill6": "landscape"}

SOURCES: tuple[Source, ...] = (
    Source("plasma-workspace-wallpapers", ("usr/share/wallpapers/*/contents/images/*",),
           keep={**_each("landscape", "BytheWater ColdRipple DarkestHour EveningGlow summer_1am"),
                 **_each("macro", "FallenLeaf OneStandsOut"), "ColorfulCups": "object",
                 "Grey": "architecture", "Kite": "sky", "Path": "forest"},
           drop=_each("art", "Altai Autumn Canopee Cascade Cluster Elarun Flow FlyingKonqui "
                             "Honeywave IceCold Kay Kokkini MilkyWay Opal PastelHills Patak "
                             "SafeLanding Shell Volna"),
           largest_only=True),
    Source("mate-backgrounds", ("usr/share/backgrounds/mate/*/*",),
           keep={**_each("macro", "Aqua Blinds FreshFlower Garden GreenMeadow LadyBird RainDrops "
                                  "TwoWings YellowFlower"),
                 "Dune": "landscape", "Storm": "landscape", "Wood": "surface"},
           drop={**_each("art", "Arc-Colors-Transparent-Wallpaper Elephants* Flow Gulp Silk "
                                "Spring Waves Float-into-MATE MATE-Stripes-* Stripes "
                                "Ubuntu-Mate-*-no-logo"), "GreenTraditional": "logo"}),
    Source("lomiri-wallpapers-16.04", ("usr/share/backgrounds/*",),
           keep={"Bridge_by_Sander_Klootwijk": "architecture", "Dragonfly_by_Bolly": "nature",
                 "Picture_0B_by_freespace": "food", "Picture_1A_by_freespace": "object",
                 "Wine_by_Jakkub_Mede": "interior", "free_by_Peter_Nerlich": "object",
                 "friends_by_Aitzol_Berasategi": "animal", "greentock_by_Peter_Nerlich": "object",
                 "life_by_Aitzol_Berasategi": "forest",
                 "seeding_by_Clements_Engelhardt": "macro",
                 **_each("landscape", "aitzgorri_by_Aitzol_Berasategi sunset_by_Aitzol_Berasategi "
                                      "picosdeeuropa_by_Aitzol_Berasategi")},
           drop={"analogpattern_by_Peter_Nerlich": "edited", "umang_by_Abhishek_Mudgal": "art"}),
    Source("lomiri-wallpapers-20.04", ("usr/share/backgrounds/*",),
           keep={"Kleiber_by_Lukas_Baubkus": "nature"},
           drop={"Fossa_by_Jasper_Roks": "art", "Infinite-Sea_by_Aury88": "composite",
                 "Painting-Colors_by__herobrine7gamer": "art"}),
    Source("lxqt-themes", ("usr/share/lxqt/wallpapers/*",),
           keep={**_each("macro", "Butterfly-Kenneth-Wimer after-the-rain appleflower butterfly "
                                  "drop flowers"),
                 **_each("landscape", "Valendas beam fog this-is-not-windows"), "cloud": "sky"},
           drop=_each("art", "kde-plasma lxqt-origami-green origami-* plasma-logo-* plasma_arch "
                             "simple_blue_widescreen triangles triangles-logo waves-logo "
                             "waves-purple-logo")),
    Source("palapeli-data", ("usr/share/palapeli/collection/*", "usr/share/palapeli/backgrounds/*"),
           keep={"castle-maintenon": "architecture", "cincinnati-bridge": "city",
                 "citrus-fruits": "food", "european-honey-bee": "macro",
                 "panther-chameleon-female": "animal"},
           drop={**_each("render", "Eliminator-Funk-2 Rear-Admiral-Diplomat-1 Time-For-Lunch-2 "
                                   "gon-defends-the-critters-1 mahogany-handjob-1")},
           licences={n: (lic, f"X-KDE-PluginInfo-License in collection/{n}.desktop")
                     for n, lic in (("castle-maintenon", "GFDL"), ("cincinnati-bridge", "PD"),
                                    ("citrus-fruits", "PD"), ("european-honey-bee", "PD"),
                                    ("panther-chameleon-female", "GFDL"))}),
    Source("tuxpaint-data", ("usr/share/tuxpaint/templates/*", "usr/share/tuxpaint/starters/*"),
           keep={**_each("nature", "burnt_bark mossy_bark mossy_log mudstone rocks spiders_web "
                                   "sun_behind_leaves"),
                 **_each("landscape", "cliff corn_maze ocean_splash ocean_waves sheep "
                                      "sun_behind_clouds trees_at_dusk"),
                 **_each("forest", "redwoods_above trees_above"), "jellyfish": "underwater",
                 "lighthouse": "architecture", "wool_mill_machine": "machine",
                 "reef-back": "underwater", "skyline-sf-dusk-back": "city"},
           drop={**_each("drawing", "carcassone chessboard chessboard-back chicken frog frame_* "
                                    "grid_* hat jetplane jigsaw* nagasaki pansy rocket shipwreck "
                                    "street tux_farmer worldmap*"),
                 **_each("cutout", "reef skyline-sf-dusk")}),
    Source("scribus-template", ("usr/share/scribus/templates/*/*.jpg",),
           keep={**_each("sky", "br2-brightness br2-halfmoon br2-moon cal2-moon br2-sunset"),
                 "br2-nature": "landscape", "menu2-pizza": "food"},
           drop={"*-craigbradney": "small", "*-petr_vanek": "small", "*-mantis": "screenshot"},
           freeform=("public-domain", "placed into public domain by their author"),
           stem=folder_stem),
    Source("kphotoalbum", ("usr/share/kphotoalbum/demo/*.jpg",),
           keep={**_each("people", "anne_helene bar55 bar55_2 donna donna_2 jesper jesper_2 "
                                   "pool pool_2 spiff spiff_2 wayne"),
                 **_each("landscape", "cold_water grand_canyon_1 grand_canyon_2 grand_canyon_3 "
                                      "new_wave_1 new_wave_2 skagen skagen_2 snow sunset"),
                 "blackie": "animal"},
           drop={"qt-logo": "logo"},
           turns={"new_wave_1": 90, "grand_canyon_1": 180, "wayne": 90, "pool_2": 270},  # index.xml
           freeform=("GPL-2+", "either version 2 of the License, or (at your option) any later")),
    Source("sddm-theme-maldives", ("usr/share/sddm/themes/maldives/*.jpg",),
           keep={"background": "landscape"}, drop={"maldives": "screenshot"}),
    Source("python-kivy-examples", ("usr/share/kivy-examples/demo/pictures/images/*",
                                    "usr/share/kivy-examples/widgets/*.png"),
           keep={"cityCC0": "city", "Wall": "architecture", "faust_github": "animal"},
           drop={"Bubbles": "art", "Ill1": "art", "*": "icon"}),
    Source("gcompris-qt-data", (".rcc/*/gcompris/src/*/**/*",), keep=_GC_KEEP,
           drop={"lang-*": "drawing", "babyshapes-*": "cutout", "solar_system-*": "astro",
                 "gravity-*": "render", "hangman-fog": "overlay",
                 **_each("painting", "details-image-*Gogh* details-image-Eglise* "
                                     "details-image-Portrait*")},
           licences=_GC_LICENCES, rcc="usr/share/gcompris-qt/rcc/*.rcc", stem=resource_stem),
    # photo3d's evaluation photos: always held out
    Source("python-matplotlib-data", ("usr/share/matplotlib/mpl-data/sample_data/*",),
           keep={"grace_hopper": "portrait"},
           drop={"Minduka_Present_Blue_Pack": "art", "logo2": "logo"},
           licences={"grace_hopper": ("PD", "U.S. Navy photograph")}, heldout=True),
    Source("python3-sklearn", ("usr/lib/python3/dist-packages/sklearn/datasets/images/*.jpg",),
           keep={"china": "architecture", "flower": "macro"},
           licences=dict.fromkeys(("china", "flower"), ("CC-BY-2.0", "images/README.txt")),
           heldout=True),
    Source("scikit-image", ("data/*.png", "data/*.jpg"), python="skimage", heldout=True,
           keep={**_each("texture", "brick grass gravel"), "astronaut": "portrait",
                 "camera": "portrait", "cell": "microscopy", "chelsea": "animal",
                 "coffee": "food", "coins": "object", "hubble_deep_field": "astro",
                 "ihc": "microscopy", "moon": "astro", "motorcycle_left": "object",
                 "motorcycle_right": "object", "retina": "medical", "rocket": "object"},
           drop={**_each("synthetic", "color chessboard_* phantom clock_motion"),
                 "logo": "logo", "horse": "drawing", "page": "text", "text": "text"},
           licences={**dict.fromkeys(("brick", "camera", "cell", "chelsea", "coffee", "grass",
                                      "gravel", "retina"), ("CC0-1.0", "skimage.data docs")),
                     **dict.fromkeys(("astronaut", "coins", "hubble_deep_field", "ihc", "rocket"),
                                     ("PD", "skimage.data docs")),
                     **dict.fromkeys(("moon", "motorcycle_left", "motorcycle_right"),
                                     ("unstated", "skimage.data docs (held out only)"))}),
)
"""Every package used, with its reviewed photos (see docs/learned.md, Training photos)."""

ART_ONLY = {
    "ukui-wallpapers": "art", "lomiri-wallpapers": "art", "gnome-backgrounds": "art",
    "desktop-base": "art", "sway-backgrounds": "logo", "xfdesktop4-data": "art",
    "debian-edu-artwork-emerald": "art", "fvwm-crystal": "art", "propaganda-debian": "tiles",
    "fluxbox": "logo", "eterm": "tiles", "wmaker-data": "tiles", "digikam-data": "textures",
}
"""Packages examined (Debian 12) and not used: no photographs, one word on what they hold."""
