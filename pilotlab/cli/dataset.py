"""`pilotlab dataset inspect BAG [--json]` and `pilotlab dataset convert FOLDER --out BAG`."""
from __future__ import annotations

import argparse
import json


def register(subparsers) -> None:
    parser = subparsers.add_parser("dataset", help="inspect rosbags, convert DeepLearningStudio datasets")
    commands = parser.add_subparsers(dest="dataset_command", metavar="ACTION", required=True)

    inspect = commands.add_parser("inspect", help="topics, types, counts, duration, image size, v/w ranges")
    inspect.add_argument("bag", help="a ROS1 .bag, a ROS2 bag folder, or a DeepLearningStudio dataset folder")
    inspect.add_argument("--command-topic", default=None, help="topic of the commands (default /F1ROS/cmd_vel)")
    inspect.add_argument("--image-topic", default=None, help="the image topic to check, as a recipe's dataset "
                                                             "reads it (default: every image topic)")
    inspect.add_argument("--json", action="store_true", help="print JSON instead of a table")
    inspect.set_defaults(func=run_inspect)

    convert = commands.add_parser("convert", help="a DeepLearningStudio folder (images + data.csv) -> a bag")
    convert.add_argument("folder", help="folder with <n>.png images and data.csv (image_name, v, w, timestamp)")
    convert.add_argument("--out", required=True, help="output: NAME.bag (ROS1) or a folder name (ROS2)")
    convert.add_argument("--storage", choices=["auto", "ros1", "sqlite3", "mcap"], default="auto",
                         help="auto: ROS1 for .bag, else ROS2 sqlite3")
    convert.add_argument("--compression", choices=["jpeg", "png"], default=None,
                         help="write sensor_msgs/CompressedImage instead of raw rgb8 images")
    convert.add_argument("--image-topic", default=None)
    convert.add_argument("--command-topic", default=None)
    convert.set_defaults(func=run_convert)


def run_inspect(args: argparse.Namespace) -> int:
    from pilotlab.data.inspect import inspect_recording

    with _ImageProgress() as progress:
        info = inspect_recording(args.bag, args.command_topic, progress=progress.update,
                                 image_topic=args.image_topic)
    if args.json:
        print(json.dumps(info, indent=1))
    else:
        print_inspection(info)
    images = info["images"].values()
    # frames would fail: an unreadable image of a folder, no image topic it can decode, or no commands
    # (`all` of no images is true: a bag without an image topic, which exited 1 without a word)
    unreadable = any(image.get("unreadable") for image in images) or all(image.get("problem") for image in images)
    return 1 if unreadable or info["commands"] is None else 0


def print_inspection(info: dict) -> None:
    from rich.console import Console
    from rich.table import Column, Table

    console = Console()
    console.print(f"[bold]{info['path']}[/bold]  {info['format']}, {info['messages']} messages, "
                  f"{info['duration_s']:.1f} s")
    if info["topics"]:
        table = Table(*(Column(name, overflow="fold") for name in ("topic", "type", "messages", "rate (Hz)")))
        for topic in info["topics"]:
            table.add_row(topic["name"], topic["type"], str(topic["count"]), f"{topic['rate_hz'] or 0:.1f}")
        console.print(table)
    if not info["images"]:
        console.print("[bold red]no images:[/] the bag has no topic of type sensor_msgs/Image or CompressedImage",
                      highlight=False)
    for name, image in info["images"].items():
        console.print(_images_line(name, image), highlight=False)
        if image.get("problem"):
            console.print(f"[bold red]cannot be read:[/] {image['problem']}", highlight=False)
        if image.get("unreadable"):
            console.print(f"[bold red]{image['unreadable']} image(s) named in {name} cannot be read[/] (first: "
                          f"{', '.join(image['unreadable_first'])}): the frames job stops at the first; replace "
                          "or remove them and their rows", highlight=False)
    commands = info["commands"]
    if commands:
        console.print(f"commands on {commands['topic']}: {commands['count']}, "
                      f"v {commands['v'][0]:.3f} .. {commands['v'][1]:.3f} m/s, "
                      f"w {commands['w'][0]:.3f} .. {commands['w'][1]:.3f} rad/s")
        if damaged := commands.get("damaged"):
            console.print(f"[bold yellow]{damaged['count']} damaged command(s)[/] ({damaged['reason']}), "
                          "dropped with their frames when read", highlight=False)
    else:
        console.print(f"[bold red]no commands:[/] the bag has no {info['command_topic']} of type geometry_msgs/Twist "
                      "or TwistStamped (name the command topic with --command-topic)", highlight=False)


def _images_line(name: str, image: dict) -> str:
    """`images on TOPIC: 200×66 png`; a folder's images all opened: each size with its count when mixed."""
    if image["size"] is None:
        return f"images in {name}: none readable"
    height, width = image["size"]
    sizes = image.get("sizes") or {}
    if len(sizes) > 1:   # preprocessing resizes each, but a mix often means images from two cameras
        mix = ", ".join(f"{size.replace('x', '×')} ({count})" for size, count in sizes.items())
        return f"images in {name}: {image['encoding']} of {len(sizes)} sizes: {mix}"
    where = "in" if "sizes" in image else "on"
    return f"images {where} {name}: {width}×{height} {image['encoding']}"


class _ImageProgress:
    """A transient bar on a terminal while a dataset folder's images are opened (thousands take a while)."""

    def __enter__(self) -> _ImageProgress:
        self.bar, self.task = None, None
        return self

    def update(self, done: int, total: int) -> None:
        if self.bar is None:
            self.bar = self._start(total)
        if self.bar:
            self.bar.update(self.task, completed=done)

    def _start(self, total: int):
        from rich.console import Console
        from rich.progress import Progress
        console = Console(stderr=True)
        if not console.is_terminal:   # a pipe or a log gets no bar (rich would leave an empty line)
            return False
        bar = Progress(console=console, transient=True)
        bar.start()
        self.task = bar.add_task("opening images", total=total)
        return bar

    def __exit__(self, *exc) -> None:
        if self.bar:
            self.bar.stop()


def run_convert(args: argparse.Namespace) -> int:
    from pilotlab.data.folder import folder_to_bag

    count = folder_to_bag(args.folder, args.out, storage=args.storage, compression=args.compression,
                          image_topic=args.image_topic, command_topic=args.command_topic)
    print(f"wrote {count} frames to {args.out}")
    return 0
