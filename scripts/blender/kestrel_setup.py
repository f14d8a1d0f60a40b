"""Set a Blender scene up for Kestrel and write its camera.json (docs/blender.md).

    blender -b scene.blend --python scripts/blender/kestrel_setup.py -- OUTPUT_FOLDER
    blender -b scene.blend --python scripts/blender/kestrel_setup.py -a -- OUTPUT_FOLDER  # and render

configures the scene's render output and view-layer passes for Kestrel (OpenEXR MultiLayer,
32-bit float, ZIP; the G-buffer, light and Denoising Data passes; motion blur off so the Vector
pass holds motion; object pass indices) and writes OUTPUT_FOLDER/camera.json: the camera and
object matrices of every frame of the scene's frame range, in the format the loader reads
(passes/exr/SceneMatrices.cpp, docs/layouts.md). Frames render to OUTPUT_FOLDER/frame_####.exr.

Options after OUTPUT_FOLDER:
    --frames A-B        frames to list in camera.json (default: the scene's frame range)
    --filter-width PX   pixel filter width: 0.01 for point-sampled G-buffers (each pixel's
                        ray through its centre), Blender's default 1.5 keeps the render
                        anti-aliased (default: leave the scene's)
    --camera-only       write camera.json only; change no render setting
    --keep-pass-index   keep the objects' pass indices (default: number the meshes 1..N
                        where they are all 0, so the object-id test can tell objects apart)
    --save              save the .blend with the settings (default: settings last this session)

The matrix math and the camera.json document need no Blender: they are plain Python (the test
suite runs them under python3 and loads the result with Kestrel's loader).
"""

import json
import math
import os
import sys

# --- plain Python: matrices as row-major nested lists, column-vector convention -------------


def matmul(a, b):
    """4x4 product a @ b."""
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def rigid_inverse(m):
    """Inverse of a rotation + translation (a camera's matrix_world without scale)."""
    rt = [[m[c][r] for c in range(3)] for r in range(3)]  # R transposed
    t = [m[r][3] for r in range(3)]
    inv = [[rt[r][0], rt[r][1], rt[r][2], -sum(rt[r][k] * t[k] for k in range(3))] for r in range(3)]
    return inv + [[0.0, 0.0, 0.0, 1.0]]


def perspective(fov_x, width, height, near, far):
    """OpenGL clip-from-camera for a horizontal field of view (radians), as Blender's
    Object.calc_matrix_camera gives with sensor fit HORIZONTAL and square pixels."""
    fx = 1.0 / math.tan(fov_x / 2.0)
    fy = fx * width / height
    return [
        [fx, 0.0, 0.0, 0.0],
        [0.0, fy, 0.0, 0.0],
        [0.0, 0.0, -(far + near) / (far - near), -2.0 * far * near / (far - near)],
        [0.0, 0.0, -1.0, 0.0],
    ]


def without_scale(m):
    """matrix_world with each axis normalised: a camera scaled in the scene still sees the same
    picture, and view must be rigid for the loader's depth and normals."""
    out = [list(row) for row in m]
    for c in range(3):
        n = math.sqrt(sum(m[r][c] ** 2 for r in range(3))) or 1.0
        for r in range(3):
            out[r][c] = m[r][c] / n
    return out


def frame_entry(frame, camera_to_world, projection, objects):
    """One element of camera.json's "frames"."""
    cam = without_scale(camera_to_world)
    view = rigid_inverse(cam)
    return {
        "frame": int(frame),
        "camera_to_world": cam,
        "view": view,
        "projection": projection,
        "view_projection": matmul(projection, view),
        "objects": objects,
    }


def camera_document(frames, resolution, fov_x, fov_y, near, far, pass_index, render_settings,
                    scene_name="scene"):
    """camera.json: what passes/exr/SceneMatrices.cpp reads (resolution, frames[].view,
    frames[].view_projection, frames[].objects, object_pass_index, render_settings), with the
    conventions written out for a reader without the docs."""
    return {
        "scene": scene_name,
        "written_by": "scripts/blender/kestrel_setup.py",
        "frames_rendered": [frames[0]["frame"], frames[-1]["frame"]] if frames else [],
        "resolution": [int(resolution[0]), int(resolution[1])],
        "fov_x_deg": math.degrees(fov_x),
        "fov_y_deg": math.degrees(fov_y),
        "near": near,
        "far": far,
        "matrix_layout": "row-major nested lists: M[row][col]; column-vector convention "
                         "p' = M @ [x, y, z, 1]^T (translation in the last column, M[r][3])",
        "matrices": {
            "camera_to_world": "camera object's matrix_world (rigid)",
            "view": "world -> camera (inverse of camera_to_world); camera looks down -Z, +Y up",
            "projection": "OpenGL clip-from-camera (Object.calc_matrix_camera)",
            "view_projection": "projection @ view (world -> clip)",
            "objects": "object name -> object-to-world matrix (matrix_world) for this frame",
        },
        "pixel_mapping": {
            "formula": "px = (ndc.x + 1) / 2 * W ;  py = (1 - ndc.y) / 2 * H   (py down from the top row)",
        },
        "depth_pass": "Depth.Z = camera-space planar depth = -z_camera",
        "object_pass_index": pass_index,
        "render_settings": render_settings,
        "frames": frames,
    }


def filter_settings(filter_type, width_px):
    """render_settings entries the loader reads for the pixel filter (filter_width_px)."""
    return {"pixel_filter": "%s, width %g px" % (filter_type, width_px),
            "filter_width_px": float(width_px)}


def write_camera_json(path, document):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(document, f, indent=1)
    os.replace(tmp, path)  # never a half-written camera.json beside the frames


def parse_args(argv):
    """Arguments after Blender's '--'."""
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    opts = {"out": None, "frames": None, "filter_width": None, "camera_only": False,
            "keep_pass_index": False, "save": False}
    i = 0
    while i < len(args):
        a = args[i]
        if a == "--frames":
            first, _, last = args[i + 1].partition("-")
            opts["frames"] = (int(first), int(last or first))
            i += 1
        elif a == "--filter-width":
            opts["filter_width"] = float(args[i + 1])
            i += 1
        elif a in ("--camera-only", "--keep-pass-index", "--save"):
            opts[a[2:].replace("-", "_")] = True
        elif a.startswith("-"):
            raise SystemExit("kestrel_setup.py: unknown option %s (see the script's docstring)" % a)
        elif opts["out"] is None:
            opts["out"] = a
        else:
            raise SystemExit("kestrel_setup.py: one OUTPUT_FOLDER, got %s too" % a)
        i += 1
    if opts["out"] is None:
        raise SystemExit("usage: blender -b scene.blend --python kestrel_setup.py -- OUTPUT_FOLDER "
                         "[--frames A-B] [--filter-width PX] [--camera-only] [--keep-pass-index] "
                         "[--save]")
    return opts


# --- Blender --------------------------------------------------------------------------------


def to_lists(m):
    return [[float(m[r][c]) for c in range(4)] for r in range(4)]


def set_if(obj, name, value):
    """Sets a property where this Blender version has it (names moved between releases)."""
    if hasattr(obj, name):
        setattr(obj, name, value)
        return True
    return False


def configure(scene, view_layer, opts):
    """Render output and passes Kestrel reads (docs/blender.md says what each buys)."""
    if scene.render.engine != "CYCLES":
        print("kestrel_setup: render engine is %s; the light passes and Denoising Data are "
              "Cycles' (switching to Cycles)" % scene.render.engine)
        scene.render.engine = "CYCLES"
    s = scene.render.image_settings
    s.file_format = "OPEN_EXR_MULTILAYER"
    s.color_depth = "32"  # half depth makes the depth tests coarse (docs/layouts.md)
    s.exr_codec = "ZIP"
    scene.render.filepath = os.path.join(os.path.abspath(opts["out"]), "frame_####")
    scene.render.use_file_extension = True
    scene.render.use_motion_blur = False  # with motion blur on, Blender writes no Vector pass
    for name in ("use_pass_combined", "use_pass_z", "use_pass_normal", "use_pass_vector",
                 "use_pass_object_index", "use_pass_position", "use_pass_emit",
                 "use_pass_environment", "use_pass_diffuse_direct", "use_pass_diffuse_indirect",
                 "use_pass_diffuse_color", "use_pass_glossy_direct", "use_pass_glossy_indirect",
                 "use_pass_glossy_color", "use_pass_transmission_direct",
                 "use_pass_transmission_indirect", "use_pass_transmission_color"):
        set_if(view_layer, name, True)
    set_if(view_layer.cycles, "denoising_store_passes", True)  # Denoising Albedo and Normal
    if opts["filter_width"] is not None:
        scene.cycles.filter_width = opts["filter_width"]


def number_objects(scene):
    """Pass indices 1..N on the meshes when every one is 0 (the object-id test needs them)."""
    meshes = [o for o in scene.objects if o.type == "MESH"]
    if meshes and all(o.pass_index == 0 for o in meshes):
        for i, o in enumerate(sorted(meshes, key=lambda o: o.name), start=1):
            o.pass_index = i


def camera_json_from_scene(scene, view_layer, opts):
    import bpy  # noqa: F401  (inside Blender only)

    cam = scene.camera
    if cam is None:
        raise SystemExit("kestrel_setup.py: the scene has no active camera")
    r = scene.render
    width = int(r.resolution_x * r.resolution_percentage / 100)
    height = int(r.resolution_y * r.resolution_percentage / 100)
    first, last = opts["frames"] or (scene.frame_start, scene.frame_end)
    objects = [o for o in scene.objects if o.type == "MESH"]
    pass_index = {o.name: int(o.pass_index) for o in objects if o.pass_index > 0}
    frames = []
    keep = scene.frame_current
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for f in range(first, last + 1):
        scene.frame_set(f)
        projection = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                            scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y)
        frames.append(frame_entry(f, to_lists(cam.matrix_world), to_lists(projection),
                                  {o.name: to_lists(o.matrix_world) for o in objects}))
    scene.frame_set(keep)
    data = cam.data
    fov_x = data.angle_x if data.type == "PERSP" else 0.0
    fov_y = 2 * math.atan(math.tan(fov_x / 2) * height / width) if fov_x else 0.0
    settings = filter_settings(getattr(scene.cycles, "pixel_filter_type", "BLACKMAN_HARRIS"),
                               scene.cycles.filter_width)
    settings.update({"engine": "%s (Blender %s)" % (r.engine, bpy.app.version_string),
                     "motion_blur": bool(r.use_motion_blur), "view_layer": view_layer.name})
    return camera_document(frames, (width, height), fov_x, fov_y, data.clip_start, data.clip_end,
                           pass_index, settings, scene.name)


def main():
    try:
        import bpy
    except ImportError:
        raise SystemExit("kestrel_setup.py runs inside Blender: blender -b scene.blend --python "
                         "kestrel_setup.py -- OUTPUT_FOLDER")

    opts = parse_args(sys.argv)
    scene = bpy.context.scene
    view_layer = bpy.context.view_layer
    if scene.camera is not None and scene.camera.data.type != "PERSP":
        print("kestrel_setup: camera %s is %s; Kestrel's reprojection assumes a perspective "
              "camera" % (scene.camera.name, scene.camera.data.type))
    if not opts["camera_only"]:
        configure(scene, view_layer, opts)
        if not opts["keep_pass_index"]:
            number_objects(scene)
    path = os.path.join(opts["out"], "camera.json")
    write_camera_json(path, camera_json_from_scene(scene, view_layer, opts))
    print("kestrel_setup: wrote %s (frames %d-%d); frames render to %s" %
          (path, *(opts["frames"] or (scene.frame_start, scene.frame_end)), scene.render.filepath))
    if opts["save"]:
        bpy.ops.wm.save_mainfile()


if __name__ == "__main__":
    main()
