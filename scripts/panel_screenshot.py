"""A painting of the DanceNet sidebar panel's real layout, not a screenshot: docs/panel.png.

The pip `bpy` module has no GUI, and no Blender 4.2+ binary could be had here, so this runs the panel's real
`draw()` against a recording stand-in for `UILayout`, fills every widget from the registered RNA (property
names, values at their defaults, enum labels, operator labels and polls), and paints that layout with Pillow in
the colours of Blender's default dark theme; its widgets are our drawings of Blender's, and the picture says so
in a line under the panel. By default it first runs the real Generate Dance on the example song, copied beside
a saved .blend so that the panel shows it as a user would see it (`//example_song.ogg`, no path of this
machine), and the panel shows a real analysis (tempo, style probabilities) and the export buttons.

    .venv/bin/python scripts/panel_screenshot.py [--song examples/example_song.ogg] [--out docs/panel.png]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import bpy
from PIL import Image, ImageDraw, ImageFont

ROOT = Path(__file__).resolve().parents[1]

# --- recording ------------------------------------------------------------------------------------


@dataclass
class Widget:
    """One button as Blender would draw it: `kind` picks the look, `text` is the label the user reads."""

    kind: str  # label, operator, check, number, menu, radio, text, pointer, progress, separator, list item
    text: str = ""
    icon: str = "NONE"
    value: str = ""  # number / menu / text / pointer: what the field shows
    selected: bool = False  # check: ticked; radio: the chosen item
    factor: float = 0.0  # progress
    enabled: bool = True
    icon_only: bool = False


@dataclass(slots=True)
class RecordingLayout:
    """Stands in for bpy.types.UILayout: records what `draw()` asks for (slots: an unknown setting raises)."""

    kind: str = "column"  # column, row, box, split, list (a UIList), panel (a sub-panel)
    align: bool = False
    title: str = ""  # panel: its header
    closed: bool = False  # panel: folded (DEFAULT_CLOSED), only its header drawn
    children: list[RecordingLayout | Widget | list[Widget]] = field(default_factory=list)
    enabled: bool = True
    active: bool = True
    scale_x: float = 1.0
    scale_y: float = 1.0
    alignment: str = "EXPAND"
    use_property_split: bool = False
    use_property_decorate: bool = False

    def _sub(self, kind: str, align: bool = False) -> RecordingLayout:
        sub = RecordingLayout(kind, align, enabled=self.enabled and self.active, scale_y=self.scale_y)
        self.children.append(sub)
        return sub

    def row(self, align: bool = False, heading: str = "") -> RecordingLayout:
        return self._sub("row", align)

    def column(self, align: bool = False, heading: str = "") -> RecordingLayout:
        return self._sub("column", align)

    def box(self) -> RecordingLayout:
        return self._sub("box")

    def split(self, factor: float = 0.0, align: bool = False) -> RecordingLayout:
        return self._sub("split", align)

    def separator(self, factor: float = 1.0) -> None:
        self.children.append(Widget("separator"))

    def label(self, text: str = "", icon: str = "NONE") -> None:
        self.children.append(Widget("label", text, icon, enabled=self.enabled))

    def progress(self, factor: float = 0.0, type: str = "BAR", text: str = "") -> None:  # bpy's own parameter names
        self.children.append(Widget("progress", text, factor=factor, enabled=self.enabled))

    def operator(self, operator: str, text: str | None = None, icon: str = "NONE", **_: Any) -> SimpleNamespace:
        module, name = operator.split(".")
        op = getattr(getattr(bpy.ops, module), name)
        label = op.get_rna_type().name if text is None else text
        enabled = self.enabled and self.active and op.poll()
        depress = _.get("depress")
        kind = "operator" if depress is None else "radio"  # a pressed-in button reads as a chosen item
        self.children.append(Widget(kind, label, icon, selected=bool(depress), enabled=enabled, icon_only=not label))
        return SimpleNamespace()  # operator properties the panel sets (kept, not drawn)

    def template_list(self, listtype_name: str, list_id: str, dataptr: bpy.types.bpy_struct, propname: str,
                      active_dataptr: bpy.types.bpy_struct, active_propname: str, rows: int = 5, **_: Any) -> None:
        """The UIList's own filter_items and draw_item, one recorded row per item shown, the active one selected."""
        ui_list = getattr(bpy.types, listtype_name)
        state = SimpleNamespace(filter_name="", use_filter_invert=False, bitflag_filter_item=1 << 30)
        items = list(getattr(dataptr, propname))
        flags, order = ui_list.filter_items(state, bpy.context, dataptr, propname)
        active = getattr(active_dataptr, active_propname)
        box = self._sub("list")
        for index in sorted((i for i, f in enumerate(flags) if f & state.bitflag_filter_item), key=order.__getitem__):
            row = box._sub("row")
            ui_list.draw_item(state, bpy.context, row, dataptr, items[index], 0, active_dataptr, active_propname,
                              index, flags[index])  # fmt: skip
            for widget in walk(row):
                widget.kind, widget.selected = "item", index == active

    def prop_search(self, data: bpy.types.bpy_struct, property: str, search_data: bpy.types.bpy_struct,
                    search_property: str, text: str = "", icon: str = "NONE") -> None:
        self.children.append(Widget("pointer", text, "BONE_DATA", value=str(getattr(data, property)),
                                    enabled=self.enabled and self.active))

    def menu(self, menu: str, text: str = "", icon: str = "NONE") -> None:
        self.children.append(Widget("menu", "", icon, value=text, enabled=self.enabled and self.active))

    def prop(
        self, data: bpy.types.bpy_struct, property: str, text: str | None = None, icon: str = "NONE",
        expand: bool = False, **_: Any,
    ) -> None:  # fmt: skip
        self.children.append(_prop_widgets(data, property, text, icon, expand, self.enabled and self.active))


def _prop_widgets(
    data: bpy.types.bpy_struct, name: str, text: str | None, icon: str, expand: bool, enabled: bool
) -> Widget | list[Widget]:
    """The widget(s) Blender draws for one property, from its RNA definition and current value."""
    rna = data.bl_rna.properties[name]
    label = rna.name if text is None else text
    value = getattr(data, name)
    if rna.type == "BOOLEAN":
        return Widget("check", label, icon, selected=bool(value), enabled=enabled)
    if rna.type in {"INT", "FLOAT"}:
        shown = f"{value:.{rna.precision}f}" if rna.type == "FLOAT" else str(value)
        return Widget("number", label, icon, value=shown, enabled=enabled)
    if rna.type == "ENUM":
        if expand:
            return [
                Widget("radio", item.name, item.icon, selected=item.identifier == value, enabled=enabled)
                for item in rna.enum_items
            ]
        return Widget("menu", label, icon, value=bpy.types.UILayout.enum_item_name(data, name, value), enabled=enabled)
    if rna.type == "POINTER":
        return Widget("pointer", label, "OBJECT_DATA", value=value.name if value else "", enabled=enabled)
    shown = value
    if rna.subtype == "FILE_PATH":
        icon = "FILEBROWSER"
    return Widget("text", label, icon, value=shown, enabled=enabled)


def record_panel(context: bpy.types.Context, panel: type | None = None) -> RecordingLayout:
    """Run the add-on's real panel `draw()` (the 3D Viewport one by default), then each of its sub-panels that
    polls true (a folded one recorded too, `closed`), and return what they laid out."""
    from blender_addon import panels

    panel = panel or panels.DANCENET_PT_view3d
    root = RecordingLayout()
    panel.draw(SimpleNamespace(layout=root), context)
    for sub in panels.SUB_PANELS[panel.bl_idname]:
        if not hasattr(sub, "poll") or sub.poll(context):
            closed = "DEFAULT_CLOSED" in getattr(sub, "bl_options", ())
            folded = RecordingLayout("panel", title=sub.bl_label, closed=closed)
            root.children.append(folded)
            sub.draw(SimpleNamespace(layout=folded), context)
    return root


def walk(node: RecordingLayout | Widget | list[Widget]) -> list[Widget]:
    """Every widget under `node`, in drawing order."""
    if isinstance(node, Widget):
        return [node]
    children = node if isinstance(node, list) else node.children
    return [w for child in children for w in walk(child)]


# --- painting (Blender 4.x default theme, UI scale 2) ---------------------------------------------

S = 2  # UI scale: 1 is Blender's default resolution scale
UNIT = 20 * S  # one widget row
GAP = 2 * S
SECTION_GAP = 8 * S
PANEL_PAD = 8 * S
BOX_PAD = 5 * S
WIDTH = 300 * S
TAB_WIDTH = 22 * S

REGION = (40, 40, 40)
PANEL = (48, 48, 48)
PANEL_LINE = (36, 36, 36)
TEXT = (229, 229, 229)
TEXT_DIM = (140, 140, 140)
BLUE = (71, 114, 179)
BUTTON = (84, 84, 84)
FIELD = (29, 29, 29)
MENU = (40, 40, 40)
BOX = (42, 42, 42)
OUTLINE = (61, 61, 61)
TAB_BAR = (29, 29, 29)
TAB = (40, 40, 40)
ORANGE = (255, 160, 40)
LIST_ACTIVE = (51, 77, 128)

_FILL = {"operator": BUTTON, "check": BUTTON, "number": BUTTON, "menu": MENU, "text": FIELD, "pointer": FIELD,
         "progress": BUTTON}  # fmt: skip


def _font(size: int) -> ImageFont.FreeTypeFont:
    """Blender's own UI font (Inter), from the bpy module's data files."""
    return ImageFont.truetype(str(Path(bpy.utils.system_resource("DATAFILES")) / "fonts" / "Inter.woff2"), size)


FONT = _font(11 * S)
TITLE_FONT = _font(12 * S)
NOTE_FONT = _font(9 * S)


def _dim(color: tuple[int, int, int], enabled: bool) -> tuple[int, int, int]:
    """Blender draws disabled widgets at half alpha over the panel."""
    return color if enabled else tuple((c + p) // 2 for c, p in zip(color, PANEL, strict=True))


def _fit(text: str, width: int, middle: bool = False) -> str:
    """Clip `text` to `width` pixels with an ellipsis (paths in the middle, like Blender)."""
    if FONT.getlength(text) <= width:
        return text
    for cut in range(1, len(text)):
        if middle:
            half = (len(text) - cut) // 2
            short = text[:half] + "…" + text[len(text) - half :]
        else:
            short = text[: len(text) - cut] + "…"
        if FONT.getlength(short) <= width:
            return short
    return "…"


def _text(
    draw: ImageDraw.ImageDraw, x: float, box: tuple[int, int, int, int], text: str, color: tuple, anchor: str = "lm"
) -> None:
    draw.text((x, (box[1] + box[3]) / 2), text, fill=color, font=FONT, anchor=anchor)


def _icon(draw: ImageDraw.ImageDraw, name: str, cx: float, cy: float, color: tuple) -> None:
    """A few of Blender's icons, drawn with primitives (the real ones are compiled into Blender)."""
    r = 6 * S
    line = max(1, S)
    if name == "PLAY":
        draw.polygon([(cx - r * 0.6, cy - r), (cx - r * 0.6, cy + r), (cx + r * 0.8, cy)], fill=color)
    elif name in {"SOUND", "PLAY_SOUND"}:
        if name == "PLAY_SOUND":
            draw.polygon([(cx - r, cy - r), (cx - r, cy + r), (cx + r * 0.2, cy)], fill=color)
            cx += r * 0.6
        draw.ellipse([cx - r * 0.6, cy + r * 0.3, cx + 0.1 * r, cy + r], fill=color)
        draw.line([cx, cy + r * 0.6, cx, cy - r], fill=color, width=line)
        draw.line([cx, cy - r, cx + r * 0.6, cy - r * 0.4], fill=color, width=line)
    elif name == "INFO":
        draw.ellipse([cx - r, cy - r, cx + r, cy + r], outline=color, width=line)
        draw.line([cx, cy - r * 0.1, cx, cy + r * 0.55], fill=color, width=line + 1)
        draw.ellipse([cx - 1.2 * S, cy - r * 0.55 - 1.2 * S, cx + 1.2 * S, cy - r * 0.55 + 1.2 * S], fill=color)
    elif name == "ERROR":
        draw.polygon([(cx, cy - r), (cx - r, cy + r * 0.8), (cx + r, cy + r * 0.8)], fill=(220, 60, 60))
        draw.line([cx, cy - r * 0.3, cx, cy + r * 0.3], fill=TEXT, width=line)
    elif name in {"EXPORT", "IMPORT"}:
        draw.line([cx - r, cy, cx - r, cy + r, cx + r, cy + r, cx + r, cy], fill=color, width=line)
        tip, tail = (cy - r, cy + r * 0.4) if name == "EXPORT" else (cy + r * 0.4, cy - r)
        draw.line([cx, tail, cx, tip], fill=color, width=line)
        draw.polygon([(cx - r * 0.5, tip + (tail - tip) * 0.4), (cx + r * 0.5, tip + (tail - tip) * 0.4), (cx, tip)],
                     fill=color)  # fmt: skip
    elif name == "TEXT":
        for k in range(4):
            y = cy - r + k * r * 0.65
            draw.line([cx - r * 0.8, y, cx + (r * 0.8 if k % 2 == 0 else r * 0.3), y], fill=color, width=line)
    elif name == "CANCEL":
        draw.line([cx - r * 0.7, cy - r * 0.7, cx + r * 0.7, cy + r * 0.7], fill=color, width=line + 1)
        draw.line([cx - r * 0.7, cy + r * 0.7, cx + r * 0.7, cy - r * 0.7], fill=color, width=line + 1)
    elif name == "FILEBROWSER":
        draw.rectangle([cx - r, cy - r * 0.55, cx + r, cy + r * 0.8], fill=color)
        draw.rectangle([cx - r, cy - r * 0.85, cx - r * 0.1, cy - r * 0.4], fill=color)
    elif name == "OBJECT_DATA":
        draw.polygon([(cx, cy - r), (cx - r, cy + r * 0.8), (cx + r, cy + r * 0.8)], outline=ORANGE, width=line)
    elif name == "SORTTIME":
        draw.polygon([(cx - r * 0.6, cy - r), (cx + r * 0.6, cy - r), (cx - r * 0.6, cy + r), (cx + r * 0.6, cy + r)],
                     outline=color, width=line)  # fmt: skip


def _widget_height(node: Widget | list[Widget], scale_y: float) -> int:
    if isinstance(node, Widget) and node.kind == "separator":
        return 4 * S
    return round(UNIT * scale_y)


def _draw_widget(
    draw: ImageDraw.ImageDraw, w: Widget, box: tuple[int, int, int, int], joined: tuple[bool, bool]
) -> None:
    """One widget in `box`; `joined` (left, right): square corners where aligned neighbours touch."""
    x0, y0, x1, y1 = box
    color = _dim(TEXT, w.enabled)
    corners = (not joined[0], not joined[1], not joined[1], not joined[0])
    if w.kind in {"label", "item"}:  # a list item: a label, highlighted when active
        if w.selected:
            draw.rounded_rectangle([x0, y0, x1, y1], radius=3 * S, fill=LIST_ACTIVE)
        x = x0 + 2 * S
        if w.icon != "NONE":
            _icon(draw, w.icon, x + UNIT / 2 - 2 * S, (y0 + y1) / 2, color)
            x += UNIT
        _text(draw, x, box, _fit(w.text, x1 - x), color)
        return
    if w.kind == "check":
        side = 14 * S
        top = (y0 + y1 - side) // 2
        draw.rounded_rectangle([x0 + 2 * S, top, x0 + 2 * S + side, top + side], radius=3 * S,
                               fill=_dim(BLUE if w.selected else BUTTON, w.enabled))  # fmt: skip
        if w.selected:
            draw.line([x0 + 5 * S, top + 7 * S, x0 + 8 * S, top + 10 * S, x0 + 13 * S, top + 4 * S],
                      fill=_dim((255, 255, 255), w.enabled), width=2 * S, joint="curve")  # fmt: skip
        _text(draw, x0 + side + 8 * S, box, _fit(w.text, x1 - x0 - side - 8 * S), color)
        return
    if w.kind == "menu" and w.text:  # a labelled dropdown: the name left, the menu on the right 60%
        split = x0 + (x1 - x0) * 2 // 5
        _text(draw, x0 + 2 * S, box, _fit(w.text, split - x0 - 4 * S), color)
        x0 = split
    fill = _FILL.get(w.kind, BUTTON)
    if w.kind == "radio" and w.selected:
        fill = BLUE
    draw.rounded_rectangle([x0, y0, x1, y1], radius=4 * S, fill=_dim(fill, w.enabled), outline=_dim(OUTLINE, w.enabled),
                           width=max(1, S // 2), corners=corners)  # fmt: skip
    mid = (y0 + y1) / 2
    if w.kind == "progress":
        inner = x0 + round((x1 - x0) * w.factor)
        if inner > x0 + 2:
            draw.rounded_rectangle([x0, y0, inner, y1], radius=4 * S, fill=BLUE, corners=corners)
        _text(draw, (x0 + x1) / 2, box, _fit(w.text, x1 - x0), color, "mm")
    elif w.kind == "number":
        _text(draw, x0 + 8 * S, box, w.text, color)
        _text(draw, x1 - 8 * S, box, w.value, color, "rm")
    elif w.kind == "menu":
        _text(draw, x0 + 8 * S, box, _fit(w.value, x1 - x0 - 26 * S), color)
        draw.polygon([(x1 - 15 * S, mid - 2 * S), (x1 - 7 * S, mid - 2 * S), (x1 - 11 * S, mid + 3 * S)], fill=color)
    elif w.kind in {"text", "pointer"}:
        right = x1
        if w.icon == "FILEBROWSER":  # the file browser button joined on the right
            right = x1 - UNIT
            draw.rounded_rectangle([right, y0, x1, y1], radius=4 * S, fill=_dim(BUTTON, w.enabled),
                                   corners=(False, True, True, False))  # fmt: skip
            _icon(draw, "FILEBROWSER", right + UNIT / 2, mid, color)
        x = x0 + 6 * S
        if w.kind == "pointer":
            _icon(draw, w.icon, x + 6 * S, mid, color)
            x += 18 * S
        _text(draw, x, box, _fit(w.value or " ", right - x - 4 * S, middle=True), color)
    else:  # operator, radio: icon and text centred
        width = FONT.getlength(w.text) + (UNIT if w.icon != "NONE" and w.text else 0)
        x = (x0 + x1 - width) / 2
        if w.icon != "NONE":
            _icon(draw, w.icon, x + (UNIT / 2 - 3 * S if w.text else width / 2), mid, color)
            x += UNIT
        if w.text:
            _text(draw, x, box, _fit(w.text, x1 - x), color)


def _layout(node: RecordingLayout | Widget | list[Widget], x: int, y: int, width: int, scale_y: float,
            draw: ImageDraw.ImageDraw | None) -> int:  # fmt: skip
    """Place (and, with `draw`, paint) `node` at (x, y) in `width`; returns its height."""
    if isinstance(node, list | Widget):
        widgets = node if isinstance(node, list) else [node]
        height = _widget_height(node, scale_y)
        if draw is not None:
            _draw_row(draw, widgets, x, y, width, height, aligned=True)  # a list is an expanded enum: joined
        return height
    if node.kind in {"row", "split"}:
        return _layout_row(node, x, y, width, draw)
    if node.kind == "panel":
        return _layout_sub_panel(node, x, y, width, draw)
    pad = BOX_PAD if node.kind in {"box", "list"} else 0
    if node.kind in {"box", "list"} and draw is not None:
        height = _layout(node, x, y, width, scale_y, None)
        draw.rounded_rectangle([x, y, x + width, y + height], radius=4 * S, fill=BOX if node.kind == "box" else FIELD,
                               outline=PANEL_LINE)  # fmt: skip
    gap = 0 if node.align else GAP
    top = y + pad
    for i, child in enumerate(node.children):
        top += _layout(child, x + pad, top, width - 2 * pad, node.scale_y, draw)
        top += gap if i < len(node.children) - 1 else 0
    return top - y + pad


def _layout_sub_panel(node: RecordingLayout, x: int, y: int, width: int, draw: ImageDraw.ImageDraw | None) -> int:
    """A sub-panel: a header line with its disclosure triangle and title, its content under it unless folded."""
    header = UNIT
    if draw is not None:
        draw.line([x - PANEL_PAD // 2, y, x + width + PANEL_PAD // 2, y], fill=PANEL_LINE, width=S)
        mid = y + header / 2
        if node.closed:
            draw.polygon([(x + 3 * S, mid - 4 * S), (x + 3 * S, mid + 4 * S), (x + 8 * S, mid)], fill=TEXT)
        else:
            draw.polygon([(x + 2 * S, mid - 2 * S), (x + 10 * S, mid - 2 * S), (x + 6 * S, mid + 3 * S)], fill=TEXT)
        draw.text((x + 16 * S, mid), node.title, fill=TEXT, font=FONT, anchor="lm")
    if node.closed:
        return header
    body = RecordingLayout(children=node.children)
    return header + GAP + _layout(body, x, y + header + GAP, width, 1.0, draw)


def _layout_row(node: RecordingLayout, x: int, y: int, width: int, draw: ImageDraw.ImageDraw | None) -> int:
    """Children side by side: icon-only buttons one unit wide, the rest sharing what is left."""
    fixed = [isinstance(c, Widget) and c.icon_only for c in node.children]
    gap = 0 if node.align else GAP
    share = round((width - UNIT * sum(fixed) - gap * (len(fixed) - 1)) / max(1, len(fixed) - sum(fixed)))
    height = max((_layout(c, 0, 0, share, node.scale_y, None) for c in node.children), default=0)
    if draw is None:
        return height
    if all(isinstance(c, Widget) for c in node.children):
        _draw_row(draw, node.children, x, y, width, height, aligned=node.align)
        return height
    left = x
    for child, is_fixed in zip(node.children, fixed, strict=True):
        _layout(child, left, y, UNIT if is_fixed else share, node.scale_y, draw)
        left += (UNIT if is_fixed else share) + gap
    return height


def _draw_row(draw: ImageDraw.ImageDraw, widgets: list[Widget], x: int, y: int, width: int, height: int,
              aligned: bool) -> None:  # fmt: skip
    """Widgets side by side; aligned ones touch and share rounded ends (expanded enums, align=True rows)."""
    gap = 0 if aligned else GAP
    fixed = sum(w.icon_only for w in widgets)
    share = (width - UNIT * fixed - gap * (len(widgets) - 1)) / max(1, len(widgets) - fixed)
    left = float(x)
    for i, w in enumerate(widgets):
        span = UNIT if w.icon_only else share
        joined = (aligned and i > 0, aligned and i < len(widgets) - 1)
        if w.kind != "separator":
            _draw_widget(draw, w, (round(left), y, round(left + span), y + height), joined)
        left += span + gap


def paint(
    root: RecordingLayout, title: str = "DanceNet", tabs: tuple[str, ...] = ("Item", "Tool", "View")
) -> Image.Image:
    """The sidebar region with its tab strip (our tab active) and the panel drawn from `root`."""
    header = round(UNIT * 1.3)
    inner = WIDTH - 2 * PANEL_PAD
    sections = [_layout(child, 0, 0, inner, 1.0, None) for child in root.children]
    height = header + sum(sections) + (len(sections) - 1) * SECTION_GAP + 3 * PANEL_PAD + NOTE_FONT.size
    image = Image.new("RGB", (WIDTH + TAB_WIDTH, height), REGION)
    draw = ImageDraw.Draw(image)

    top = PANEL_PAD
    bottom = height - PANEL_PAD - NOTE_FONT.size
    draw.rounded_rectangle([PANEL_PAD // 2, top, WIDTH - PANEL_PAD // 2, bottom], radius=5 * S, fill=PANEL)
    draw.polygon([(PANEL_PAD + 2 * S, top + header / 2 - 3 * S), (PANEL_PAD + 10 * S, top + header / 2 - 3 * S),
                  (PANEL_PAD + 6 * S, top + header / 2 + 2 * S)], fill=TEXT)  # fmt: skip
    draw.text((PANEL_PAD + 16 * S, top + header / 2), title, fill=TEXT, font=TITLE_FONT, anchor="lm")
    y = top + header + PANEL_PAD // 2
    for child in root.children:  # the panel's root column: sections a little apart, as Blender spaces them
        y += _layout(child, PANEL_PAD, y, inner, 1.0, draw) + SECTION_GAP

    note = "Painted from the panel's real layout; not a Blender capture"
    draw.text((PANEL_PAD, height - PANEL_PAD // 2), note, fill=TEXT_DIM, font=NOTE_FONT, anchor="ld")
    draw.rectangle([WIDTH, 0, WIDTH + TAB_WIDTH, height], fill=TAB_BAR)
    y = 4 * S
    for name in (*tabs, title):
        length = round(FONT.getlength(name)) + 16 * S
        active = name == title
        draw.rounded_rectangle([WIDTH, y, WIDTH + TAB_WIDTH - 3 * S, y + length], radius=3 * S,
                               fill=PANEL if active else TAB, corners=(False, True, True, False))  # fmt: skip
        label = Image.new("RGBA", (length, TAB_WIDTH - 3 * S), (0, 0, 0, 0))
        ImageDraw.Draw(label).text((length / 2, label.height / 2), name, font=FONT, anchor="mm",
                                   fill=TEXT if active else TEXT_DIM)  # fmt: skip
        rotated = label.rotate(-90, expand=True)  # Blender reads sidebar tabs top to bottom
        image.paste(rotated, (WIDTH, y), rotated)
        y += length + 2 * S
    return image


# --- the picture ----------------------------------------------------------------------------------


def song_in_project(song: Path, project: Path) -> str:
    """Save the scene as a .blend in `project` with a copy of `song` beside it and return the song's path as a
    user's panel shows it, relative to the .blend ("//example_song.ogg"): no path of the machine that paints."""
    shutil.copy(song, project / song.name)
    bpy.ops.wm.save_as_mainfile(filepath=str(project / "dance.blend"))
    return f"//{song.name}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--song", type=Path, default=ROOT / "examples" / "example_song.ogg")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "panel.png")
    parser.add_argument("--no-generate", action="store_true", help="draw the panel before any generation")
    args = parser.parse_args(argv)

    sys.path.insert(0, str(ROOT))
    import blender_addon

    bpy.ops.wm.read_factory_settings(use_empty=True)
    blender_addon.register()
    props = bpy.context.scene.dancenet
    with tempfile.TemporaryDirectory(prefix="dancenet-panel-") as project:
        props.music_source, props.music_file = "FILE", song_in_project(args.song, Path(project))
        if not args.no_generate and bpy.ops.dancenet.generate() != {"FINISHED"}:
            print("panel_screenshot: Generate Dance failed (see above)", file=sys.stderr)
            return 1
        image = paint(record_panel(bpy.context))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    image.save(args.out, optimize=True)
    print(f"panel_screenshot: {args.out} ({image.width}x{image.height})")
    blender_addon.unregister()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
