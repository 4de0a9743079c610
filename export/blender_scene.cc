// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/blender_scene.h"

#include <algorithm>
#include <sstream>

#include "thinslab/core/file.h"

namespace thinslab {

namespace {

std::string Tuple(const Eigen::Vector3d& v) {
  return "(" + SceneNumber(v.x()) + ", " + SceneNumber(v.y()) + ", " + SceneNumber(v.z()) + ")";
}

std::string Tuple(const Eigen::Vector2d& v) { return "(" + SceneNumber(v.x()) + ", " + SceneNumber(v.y()) + ")"; }

// A comment line: no line breaks inside.
std::string OneLine(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

// What builds the scene from SCENE (the same for every export; the numbers come before it).
constexpr char kBuilder[] = R"PY(
HERE = os.path.dirname(os.path.abspath(__file__))


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="scene.py", description="builds the exported thinslab scene")
    parser.add_argument("--save", help="save the scene as this .blend file")
    parser.add_argument("--render", help="render the camera's image to this PNG (or .exr) file")
    parser.add_argument("--samples", type=int, default=64, help="Cycles samples per pixel")
    parser.add_argument("--resolution-percent", type=int, default=100, help="image size in percent")
    parser.add_argument("--passes", metavar="PREFIX",
                        help="the round trip's renders (32-bit EXR): PREFIX_reference.exr without the layer, "
                             "PREFIX_shadow_1.exr and PREFIX_shadow_2.exr with it (two independent seeds); for a "
                             "laser probe PREFIX_lobe_1.exr and PREFIX_lobe_2.exr (multilayer: a pass per ring); "
                             "for a dot monitor PREFIX_dot<k>_1.exr and PREFIX_dot<k>_2.exr per dot")
    return parser.parse_args(argv)


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def rectangle(name, lo, hi, z, normal_down):
    """The rectangle lo..hi at z; uv v = 1 - (y - lo.y) / height, as Blender puts an image's row 0 at v = 1."""
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    corners = [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]
    verts = [bm.verts.new((x, y, z)) for x, y in corners]
    face = bm.faces.new(list(reversed(verts)) if normal_down else verts)
    uv = bm.loops.layers.uv.new("UVMap")
    for loop in face.loops:
        x, y = loop.vert.co.x, loop.vert.co.y
        loop[uv].uv = ((x - lo[0]) / (hi[0] - lo[0]), 1.0 - (y - lo[1]) / (hi[1] - lo[1]))
    bm.to_mesh(mesh)
    bm.free()
    return link(bpy.data.objects.new(name, mesh))


def box(name, lo, hi, z0, z1):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    verts = [bm.verts.new((x, y, z)) for z in (z0, z1) for x, y in
             [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]]
    for face in [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]:
        bm.faces.new([verts[k] for k in face])
    bm.to_mesh(mesh)
    bm.free()
    return link(bpy.data.objects.new(name, mesh))


def data_image(nodes, relative_path):
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = bpy.data.images.load(os.path.join(HERE, relative_path), check_existing=True)
    texture.image.colorspace_settings.name = "Non-Color"
    texture.interpolation = "Closest"
    texture.extension = "EXTEND"
    return texture


def new_material(name):
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    material.node_tree.nodes.clear()
    return material, material.node_tree.nodes, material.node_tree.links


def glass(name, eta, distribution, alpha_texture):
    material, nodes, links = new_material(name)
    output = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfGlass")
    bsdf.distribution = distribution
    bsdf.inputs["IOR"].default_value = eta
    if alpha_texture:
        # Cycles squares its roughness input: roughness = sqrt(alpha).
        root = nodes.new("ShaderNodeMath")
        root.operation = "SQRT"
        links.new(data_image(nodes, alpha_texture).outputs["Color"], root.inputs[0])
        links.new(root.outputs[0], bsdf.inputs["Roughness"])
    else:
        bsdf.inputs["Roughness"].default_value = 0.0
    links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    return material


def layer_volume(layer, thickness):
    material, nodes, links = new_material("layer")
    output = nodes.new("ShaderNodeOutputMaterial")
    if layer["tau"]:
        coordinates = nodes.new("ShaderNodeTexCoord")
        flip = nodes.new("ShaderNodeMapping")  # Generated y runs 0..1 from min y; the image's row 0 is v = 1.
        flip.inputs["Scale"].default_value = (1.0, -1.0, 1.0)
        flip.inputs["Location"].default_value = (0.0, 1.0, 0.0)
        tau = data_image(nodes, layer["tau"])
        links.new(coordinates.outputs["Generated"], flip.inputs["Vector"])
        links.new(flip.outputs["Vector"], tau.inputs["Vector"])
        tau_output = tau.outputs["Color"]
    else:  # A uniform layer: a constant density, which Cycles samples as a homogeneous volume.
        tau = nodes.new("ShaderNodeValue")
        tau.outputs[0].default_value = layer["uniform_tau"]
        tau_output = tau.outputs[0]
    scatter = nodes.new("ShaderNodeVolumeScatter")
    scatter.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    scatter.inputs["Anisotropy"].default_value = layer["g"]
    absorb = nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)  # sigma_a = density (1 - colour).
    for shader, per_metre in ((scatter, layer["albedo"] / thickness), (absorb, (1.0 - layer["albedo"]) / thickness)):
        density = nodes.new("ShaderNodeMath")
        density.operation = "MULTIPLY"
        density.inputs[1].default_value = per_metre
        links.new(tau_output, density.inputs[0])
        links.new(density.outputs[0], shader.inputs["Density"])
    both = nodes.new("ShaderNodeAddShader")
    links.new(scatter.outputs[0], both.inputs[0])
    links.new(absorb.outputs[0], both.inputs[1])
    links.new(both.outputs[0], output.inputs["Volume"])
    return material


def emission(name, strength=1.0):
    """Radiance `strength`: Cycles renders an emitter of strength 1 seen directly as 1."""
    material, nodes, links = new_material(name)
    output = nodes.new("ShaderNodeOutputMaterial")
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = strength
    links.new(emit.outputs["Emission"], output.inputs["Surface"])
    return material


def diffuse(name, albedo):
    material, nodes, links = new_material(name)
    output = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    return material


def orient(obj, z_axis, position):
    """Places obj at position with its local +z along z_axis (lights shine along their -z)."""
    z = Vector(z_axis).normalized()
    helper = Vector((1.0, 0.0, 0.0)) if abs(z.x) < 0.9 else Vector((0.0, 1.0, 0.0))
    x = (helper - helper.dot(z) * z).normalized()
    y = z.cross(x)
    obj.matrix_world = Matrix([[x.x, y.x, z.x, position[0]], [x.y, y.y, z.y, position[1]],
                               [x.z, y.z, z.z, position[2]], [0, 0, 0, 1]])


def shadow_rig(rig):
    """The capture's shadow-map rig: a Lambertian board below the layer, a collimated light."""
    half = 1.0
    rectangle("board", (-half, -half), (half, half), -rig["board_distance"], False).data.materials.append(
        diffuse("board", rig["board_albedo"]))
    sun = bpy.data.lights.new("projector", "SUN")
    sun.energy = 1.0  # Irradiance on a surface facing the light; the round trip uses ratios.
    sun.angle = 0.0   # Collimated.
    orient(link(bpy.data.objects.new("projector", sun)), [-c for c in rig["light_propagation"]], (0.0, 0.0, 1.0))


def annulus(name, centre, inner, outer, z, segments=128):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    ring = [[bm.verts.new((centre[0] + r * math.cos(2 * math.pi * k / segments),
                           centre[1] + r * math.sin(2 * math.pi * k / segments), z)) for k in range(segments)]
            for r in (inner, outer)]
    for k in range(segments):
        j = (k + 1) % segments
        bm.faces.new([ring[0][k], ring[1][k], ring[1][j], ring[0][j]])  # Normal +z: towards the layer.
    bm.to_mesh(mesh)
    bm.free()
    return link(bpy.data.objects.new(name, mesh))


def laser_probe(probe):
    """The laser rig by reciprocity (render_scene.h LaserProbe): ring k of the board is a
    Lambertian emitter of radiance 1 in light group ring<k>, seen through the layer by an
    orthographic camera looking along the beam over its cross-section."""
    view_layer = bpy.context.scene.view_layers[0]
    material = emission("ring")
    for k, (inner, outer) in enumerate(probe["rings"]):
        ring = annulus("ring%d" % k, probe["beam_centre"], inner, outer, -probe["board_distance"])
        ring.data.materials.append(material)
        ring.visible_camera = False
        view_layer.lightgroups.add(name="ring%d" % k)
        ring.lightgroup = "ring%d" % k
    camera_data = bpy.data.cameras.new("camera")
    camera_data.type = "ORTHO"
    camera_data.ortho_scale = probe["view_size"]
    camera_data.clip_start = 1e-5
    camera_data.clip_end = 100.0
    camera = link(bpy.data.objects.new("camera", camera_data))
    camera.location = (probe["beam_centre"][0], probe["beam_centre"][1], probe["board_distance"])
    return camera


def dot_monitor(monitor):
    """The dot-scan monitor: one Lambertian disc per dot (named dot<k>), the rest black."""
    material = emission("dot", monitor["radiance"])
    for k, (centre, normal, radius) in enumerate(monitor["dots"]):
        mesh = bpy.data.meshes.new("dot%d" % k)
        bm = bmesh.new()
        bmesh.ops.create_circle(bm, cap_ends=True, segments=32, radius=radius)
        bm.to_mesh(mesh)
        bm.free()
        disc = link(bpy.data.objects.new("dot%d" % k, mesh))
        disc.data.materials.append(material)
        orient(disc, normal, centre)


def build():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    for bounces in ("max_bounces", "transmission_bounces", "transparent_max_bounces"):
        setattr(scene.cycles, bounces, 64)
    scene.cycles.volume_bounces = 16
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise.
    scene.cycles.use_adaptive_sampling = False  # Every pixel gets --samples: the round trip's noise estimate.
    scene.view_settings.view_transform = "Standard"
    scene.render.resolution_x, scene.render.resolution_y = SCENE["image"]
    world = bpy.data.worlds.new("black")
    world.use_nodes = False
    world.color = (0.0, 0.0, 0.0)
    scene.world = world

    lo = SCENE["grid_min"]
    hi = (lo[0] + SCENE["grid_size"][0], lo[1] + SCENE["grid_size"][1])
    slab = SCENE["slab"]
    if slab:
        rectangle("slab_camera_side", lo, hi, 0.0, False).data.materials.append(
            glass("slab_camera_side", slab["eta"], slab["distribution"], slab["bottom_alpha"]))
        rectangle("slab_monitor_side", lo, hi, -slab["thickness"], True).data.materials.append(
            glass("slab_monitor_side", slab["eta"], slab["distribution"], slab["top_alpha"]))
    layer = SCENE["layer"]
    rig = SCENE["shadow_rig"]
    probe = SCENE["laser_probe"]
    if layer and probe:
        # Seen by the probe camera: its rays cross the layer along the beam.
        thickness = min(layer["thickness"], 0.5 * probe["board_distance"])
        box("layer", lo, hi, -thickness, 0.0).data.materials.append(layer_volume(layer, thickness))
    elif layer and rig:
        # On the pane's board side and seen by light only: the camera views the board directly.
        thickness = min(layer["thickness"], 0.5 * rig["board_distance"])
        volume = box("layer", lo, hi, -thickness, 0.0)
        volume.data.materials.append(layer_volume(layer, thickness))
        volume.visible_camera = False
    elif layer:
        box("layer", lo, hi, 0.0, layer["thickness"]).data.materials.append(layer_volume(layer, layer["thickness"]))
        pane = glass("pane", layer["glass_eta"], "SHARP", None)
        top = -1e-6  # 1 um below the layer: coincident surfaces would intersect ambiguously.
        rectangle("pane_camera_side", lo, hi, top, False).data.materials.append(pane)
        rectangle("pane_monitor_side", lo, hi, top - layer["glass_thickness"], True).data.materials.append(pane)
    if probe:
        scene.render.resolution_x = scene.render.resolution_y = probe["image"]
        scene.cycles.pixel_filter_type = "BOX"
        scene.cycles.filter_width = 1.0
        scene.camera = laser_probe(probe)
        return scene
    monitor = SCENE["dot_monitor"]
    if rig or monitor:
        if rig:
            shadow_rig(rig)
        else:
            dot_monitor(monitor)
        scene.cycles.pixel_filter_type = "BOX"  # A camera pixel integrates its own square.
        scene.cycles.filter_width = 1.0
    else:
        light = SCENE["backlight"]
        centre = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]))
        half = light["half_size"]
        rectangle("backlight", (centre[0] - half, centre[1] - half), (centre[0] + half, centre[1] + half),
                  -light["distance"], False).data.materials.append(emission("backlight"))

    camera_data = bpy.data.cameras.new("camera")
    camera_data.sensor_fit = "HORIZONTAL"
    intrinsics = SCENE["intrinsics"]
    if intrinsics:
        # OpenCV's pinhole: fx sets the horizontal angle; Blender shifts in units of the image's
        # larger side, and its pixel centres sit at half-integers (OpenCV's at integers).
        width, height = SCENE["image"]
        camera_data.sensor_width = 36.0
        camera_data.lens = intrinsics["fx"] * camera_data.sensor_width / width
        scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = 1.0, intrinsics["fx"] / intrinsics["fy"]
        camera_data.shift_x = ((width - 1) / 2 - intrinsics["cx"]) / max(width, height)
        camera_data.shift_y = (intrinsics["cy"] - (height - 1) / 2) / max(width, height)
    else:
        camera_data.angle_x = SCENE["fov_x"]
    camera_data.clip_start = 1e-4
    camera_data.clip_end = 100.0
    camera = link(bpy.data.objects.new("camera", camera_data))
    eye, target, up = (Vector(SCENE["camera"][key]) for key in ("eye", "target", "up"))
    back = (eye - target).normalized()  # Blender cameras look along their -z, +y up.
    right = up.cross(back).normalized()
    true_up = back.cross(right)
    camera.matrix_world = Matrix([[right.x, true_up.x, back.x, eye.x], [right.y, true_up.y, back.y, eye.y],
                                  [right.z, true_up.z, back.z, eye.z], [0, 0, 0, 1]])
    scene.camera = camera
    return scene


def main():
    args = parse_args()
    scene = build()
    scene.cycles.samples = args.samples
    scene.render.resolution_percentage = args.resolution_percent
    print("thinslab scene:", ", ".join(sorted(obj.name for obj in scene.objects)))
    if args.save:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save))
    if args.passes:
        scene.render.image_settings.file_format = "OPEN_EXR"
        scene.render.image_settings.color_depth = "32"
        if SCENE["laser_probe"]:  # Two seeds; each ring's light group is a pass of the multilayer EXR.
            scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
        if SCENE["dot_monitor"]:  # Two seeds per dot, the other dots dark.
            for k in range(len(SCENE["dot_monitor"]["dots"])):
                for obj in scene.objects:
                    if obj.name.startswith("dot"):
                        obj.hide_render = obj.name != "dot%d" % k
                for seed in (1, 2):
                    scene.cycles.seed = seed
                    scene.render.filepath = os.path.abspath("%s_dot%d_%d.exr" % (args.passes, k, seed))
                    bpy.ops.render.render(write_still=True)
        passes = () if SCENE["dot_monitor"] else (("lobe_1", 1, True), ("lobe_2", 2, True)) if SCENE["laser_probe"] else (
            ("reference", 0, False), ("shadow_1", 1, True), ("shadow_2", 2, True))
        for name, seed, with_layer in passes:
            for obj in scene.objects:
                if obj.name == "layer":
                    obj.hide_render = not with_layer
            scene.cycles.seed = seed
            scene.render.filepath = os.path.abspath(args.passes + "_" + name + ".exr")
            bpy.ops.render.render(write_still=True)
    if args.render:
        path = os.path.abspath(args.render)
        scene.render.image_settings.file_format = "OPEN_EXR" if path.endswith(".exr") else "PNG"
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True)


main()
)PY";

}  // namespace

std::string BlenderScript(const RenderScene& scene, const SceneTextures& textures) {
  const SceneCamera camera = CameraOf(scene);
  std::ostringstream out;
  out << "# thinslab export blender of " << OneLine(scene.source) << " (docs/export.md).\n"
      << "# Units: metres. Frame: the sample plane is z = 0, the camera on +z, the backlight on -z.\n";
  for (const std::string& note : scene.notes) out << "# - " << OneLine(note) << "\n";
  out << "#\n# blender -b --factory-startup --python-exit-code 1 --python scene.py -- [--save FILE.blend] "
         "[--render FILE.png] [--samples N]\n"
      << "import argparse\nimport math\nimport os\nimport sys\n\nimport bmesh\nimport bpy\nfrom mathutils import "
         "Matrix, Vector\n\n"
      << "SCENE = {\n"
      << "    \"grid_min\": " << Tuple(scene.grid.min_m) << ",\n"
      << "    \"grid_size\": " << Tuple(scene.grid.size_m()) << ",\n"
      << "    \"image\": (" << scene.image_width << ", " << scene.image_height << "),\n"
      << "    \"fov_x\": " << SceneNumber(scene.fov_x_rad) << ",\n"
      << "    \"camera\": {\"eye\": " << Tuple(camera.eye) << ", \"target\": " << Tuple(camera.target)
      << ", \"up\": " << Tuple(camera.up) << "},\n"
      << "    \"backlight\": {\"distance\": " << SceneNumber(scene.backlight_distance_m)
      << ", \"half_size\": " << SceneNumber(scene.backlight_half_size_m) << "},\n";
  if (scene.intrinsics) {
    const PinholeIntrinsics& k = *scene.intrinsics;
    out << "    \"intrinsics\": {\"fx\": " << SceneNumber(k.fx) << ", \"fy\": " << SceneNumber(k.fy)
        << ", \"cx\": " << SceneNumber(k.cx) << ", \"cy\": " << SceneNumber(k.cy) << "},\n";
  } else {
    out << "    \"intrinsics\": None,\n";
  }
  if (scene.shadow_rig) {
    const ShadowRig& rig = *scene.shadow_rig;
    out << "    \"shadow_rig\": {\"board_distance\": " << SceneNumber(rig.board_distance_m)
        << ", \"board_albedo\": " << SceneNumber(rig.board_albedo)
        << ", \"light_propagation\": " << Tuple(rig.light_propagation) << "},\n";
  } else {
    out << "    \"shadow_rig\": None,\n";
  }
  if (scene.laser_probe) {
    const LaserProbe& probe = *scene.laser_probe;
    out << "    \"laser_probe\": {\"board_distance\": " << SceneNumber(probe.board_distance_m)
        << ", \"beam_centre\": " << Tuple(probe.beam_centre_m) << ", \"view_size\": " << SceneNumber(probe.view_size_m)
        << ", \"image\": " << probe.image_px << ",\n        \"rings\": [";
    for (size_t k = 0; k < probe.ring_inner_m.size(); ++k) {
      out << (k ? ", " : "") << "(" << SceneNumber(probe.ring_inner_m[k]) << ", " << SceneNumber(probe.ring_outer_m[k])
          << ")";
    }
    out << "]},\n";
  } else {
    out << "    \"laser_probe\": None,\n";
  }
  if (scene.dot_monitor) {
    const DotMonitor& monitor = *scene.dot_monitor;
    out << "    \"dot_monitor\": {\"radiance\": " << SceneNumber(monitor.radiance) << ", \"dots\": [";
    for (size_t k = 0; k < monitor.dots.size(); ++k) {
      const DotMonitor::Dot& dot = monitor.dots[k];
      out << (k ? ",\n        " : "") << "(" << Tuple(dot.centre_m) << ", " << Tuple(dot.normal) << ", "
          << SceneNumber(dot.radius_m) << ")";
    }
    out << "]},\n";
  } else {
    out << "    \"dot_monitor\": None,\n";
  }
  if (scene.slab) {
    const RoughSlab& slab = *scene.slab;
    out << "    \"slab\": {\"eta\": " << SceneNumber(slab.eta) << ", \"thickness\": " << SceneNumber(slab.thickness_m)
        << ", \"distribution\": \"" << (slab.distribution == "beckmann" ? "BECKMANN" : "GGX") << "\", \"top_alpha\": \""
        << textures.top_alpha << "\", \"bottom_alpha\": \"" << textures.bottom_alpha << "\"},\n";
  } else {
    out << "    \"slab\": None,\n";
  }
  if (scene.layer) {
    const ScatteringLayer& layer = *scene.layer;
    out << "    \"layer\": {\"tau\": " << (textures.tau.empty() ? "None" : "\"" + textures.tau + "\"")
        << ", \"uniform_tau\": " << SceneNumber(std::max(layer.uniform_tau, 0.0)) << ", \"g\": " << SceneNumber(layer.g)
        << ", \"albedo\": " << SceneNumber(layer.albedo) << ", \"thickness\": " << SceneNumber(layer.thickness_m)
        << ", \"glass_eta\": " << SceneNumber(layer.glass_eta)
        << ", \"glass_thickness\": " << SceneNumber(layer.glass_thickness_m) << "},\n";
  } else {
    out << "    \"layer\": None,\n";
  }
  out << "}\n" << kBuilder;
  return out.str();
}

Status WriteBlenderScene(const RenderScene& scene, const std::string& dir, const Provenance& provenance) {
  SceneTextures textures;
  THINSLAB_RETURN_IF_ERROR(WriteSceneTextures(scene, dir, provenance, &textures));
  return WriteFileAtomically(JoinPath(dir, "scene.py"), BlenderScript(scene, textures));
}

}  // namespace thinslab
