"""`plem scene list|add|remove|clear|attach|detach`: the collision objects the robot's planner plans around."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from plem.cli.output import new_table, stdout
from plem.cli.robot import RobotId, connect_robot

if TYPE_CHECKING:
    from plem.planning.scene import PlanningScene, SceneObject

app = typer.Typer(help="Show and change the planning scene: boxes, spheres, cylinders and meshes the planner avoids.",
                  no_args_is_help=True)


def _describe_shape(item: SceneObject) -> str:
    entry = item.to_json()
    for key in ("box", "sphere", "cylinder", "mesh"):
        if key in entry:
            return f"{key} {entry[key]}"
    return "?"


def _show(robot_id: str, scene: PlanningScene) -> None:
    objects = scene.objects()
    if not objects:
        stdout.print(f"{robot_id}: the scene is empty", markup=False)
        return
    table = new_table(f"{robot_id}: {len(objects)} objects", "name", "shape", "position m", "orientation xyzw",
                      "frame", "attached to")
    for item in objects:
        table.add_row(item.name, _describe_shape(item), " ".join(f"{v:+.3f}" for v in item.pose.position),
                      " ".join(f"{v:+.3f}" for v in item.pose.orientation), item.frame, item.attached_to or "")
    stdout.print(table)


@app.command("list")
def list_objects(robot_id: RobotId = None) -> None:
    """List the scene's objects with their shapes and poses."""
    with connect_robot(robot_id) as client:
        _show(client.robot_id, client.planning_scene())


@app.command("add")
def add(file: Annotated[Path, typer.Argument(help="YAML file of objects (docs/planning.md).")],
        robot_id: RobotId = None) -> None:
    """Add the objects of a scene file (an object of the same name is replaced)."""
    from plem.planning.scene import read_scene_file

    objects = read_scene_file(file)
    with connect_robot(robot_id) as client:
        client.add_objects(*objects)
        stdout.print(f"{client.robot_id}: added {', '.join(item.name for item in objects) or 'nothing'}",
                     markup=False)


@app.command("remove")
def remove(names: Annotated[list[str], typer.Argument(help="Objects to remove.")], robot_id: RobotId = None) -> None:
    """Remove objects by name."""
    with connect_robot(robot_id) as client:
        for name in names:
            client.remove_object(name)
        stdout.print(f"{client.robot_id}: removed {', '.join(names)}", markup=False)


@app.command("clear")
def clear(robot_id: RobotId = None) -> None:
    """Remove every object."""
    with connect_robot(robot_id) as client:
        client.clear_scene()
        stdout.print(f"{client.robot_id}: the scene is empty", markup=False)


@app.command("attach")
def attach(name: Annotated[str, typer.Argument(help="World object to attach.")],
           link: Annotated[str, typer.Option("--link", help="Link that holds it (default: the group's tip).")] = "",
           touch_links: Annotated[list[str] | None, typer.Option("--touch-link", help="A link it may touch "
                                                                 "(repeat for several).")] = None,
           robot_id: RobotId = None) -> None:
    """Attach a world object to a link where it is now: it then moves with the arm."""
    with connect_robot(robot_id) as client:
        client.attach_object(name, link, touch_links or [])
        stdout.print(f"{client.robot_id}: {name} attached to {link or 'the tool'}", markup=False)


@app.command("detach")
def detach(name: Annotated[str, typer.Argument(help="Attached object to leave in the world.")],
           robot_id: RobotId = None) -> None:
    """Leave an attached object in the world where it is now."""
    with connect_robot(robot_id) as client:
        client.detach_object(name)
        stdout.print(f"{client.robot_id}: {name} detached", markup=False)
