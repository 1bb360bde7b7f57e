# FreeCAD 0.20 headless CAM (Path) job -> grbl G-code.
# Run:  OUT=pocket.nc OPS=pocket,profile POSTARGS="--no-show-editor --no-header" freecadcmd make_job.py
# Env:  OUT=/path/out.nc (default pocket.nc)
#       OPS=comma list of operations, posted in this fixed order whatever the list's order:
#           drill (G81), dwell (G82), peck (G83), pocket, adaptive, profile, pocketprofile
#           (inside profile of the pocket), surface (3D Surface, needs OpenCamLib)
#       FEATURES=comma list of what the part has besides the 60x40x10 block with its
#           30x20x5 pocket: holes (4 x 5 mm, 8 deep, in the block's corners),
#           starthole (5 mm at the pocket's centre, 3 mm below its floor),
#           fillet (R8 rounds on the block's two long top edges). Default: none.
#       TOOLS=op=tool,... overrides of each operation's tool (default: drill/dwell/peck=drill5,
#           pocket/adaptive/profile/pocketprofile=em3, surface=ball3); tools: em3, em6, em2,
#           drill5, ball3 (each keeps its tool number whatever job it is in)
#       POSTARGS="--no-show-editor --no-header" (grbl_post args; --no-header drops the timestamp)
import os, sys
import FreeCAD, Part, Path

# FreeCAD 0.20's PathSurface does `import ocl`; PyPI's opencamlib wheel (pip install --target DIR
# opencamlib, DIR on PYTHONPATH) names the module opencamlib.ocl: alias it before the import.
try:
    import ocl  # noqa: F401
except ImportError:
    try:
        from opencamlib import ocl
        sys.modules["ocl"] = ocl
    except ImportError:
        pass

from PathScripts import PathJob, PathToolBit, PathToolController
from PathScripts import PathPocketShape, PathProfile, PathAdaptive, PathUtil, PathDrilling
from PathScripts.PathPostProcessor import PostProcessor

OUT = os.environ.get("OUT", "pocket.nc")
OPS = os.environ.get("OPS", "pocket,profile").split(",")
FEATURES = [f for f in os.environ.get("FEATURES", "").split(",") if f]
TOOLS = dict(kv.split("=") for kv in os.environ.get("TOOLS", "").split(",") if kv)

doc = FreeCAD.newDocument("millac")

# --- model: 60x40x10 block with a 30x20x5 pocket (Part boolean cut)
blk = doc.addObject("Part::Box", "Block")
blk.Length, blk.Width, blk.Height = 60, 40, 10
cutter = doc.addObject("Part::Box", "PocketVolume")
cutter.Length, cutter.Width, cutter.Height = 30, 20, 10
cutter.Placement.Base = FreeCAD.Vector(15, 10, 5)
part = doc.addObject("Part::Cut", "Part")
part.Base, part.Tool = blk, cutter
doc.recompute()
shape = part.Shape
if "fillet" in FEATURES:
    # R8 on the two long top edges (along X at Y=0 and Y=40, Z=10): a curved top for Surface
    edges = [e for e in shape.Edges
             if abs(e.BoundBox.ZMin - 10) < 1e-6 and abs(e.BoundBox.ZMax - 10) < 1e-6
             and abs(e.BoundBox.XLength - 60) < 1e-6]
    shape = shape.makeFillet(8.0, edges)
holes = []
if "holes" in FEATURES:
    holes += [(5, 5, 2, 10), (55, 5, 2, 10), (5, 35, 2, 10), (55, 35, 2, 10)]  # x, y, zbot, ztop
if "starthole" in FEATURES:
    holes += [(30, 20, 2, 5)]
for x, y, zb, zt in holes:
    shape = shape.cut(Part.makeCylinder(2.5, zt - zb + 1, FreeCAD.Vector(x, y, zb)))
if shape is not part.Shape:
    feat = doc.addObject("Part::Feature", "PartFeatures")
    feat.Shape = shape.removeSplitter()
    part = feat
    doc.recompute()

# --- job (clones the model, creates Stock + SetupSheet)
job = PathJob.Create("Job", [part])
job.PostProcessor = "grbl"
job.PostProcessorArgs = "--no-show-editor"
job.PostProcessorOutputFile = OUT
# default stock = model bbox + 1 mm on every side; make stock == model bbox
for ext in ("ExtXneg", "ExtXpos", "ExtYneg", "ExtYpos", "ExtZneg", "ExtZpos"):
    setattr(job.Stock, ext, 0.0)
doc.recompute()

# --- tools: ToolBits from the shipped shapes, one tool controller each, made when an op uses it
bitdir = os.path.join(FreeCAD.getResourceDir(), "Mod/Path/Tools/Bit")
# key: (number, .fctb template, diameter, bit label, TC name, feed, plunge mm/min, rpm)
TOOLDEFS = {
    "em3": (1, "5mm_Endmill.fctb", 3.0, "3mm Endmill", "TC_3mm", 600, 200, 12000),
    "drill5": (2, "5mm_Drill.fctb", 5.0, "5mm Drill", "TC_drill5", 300, 100, 3000),
    "em6": (3, "5mm_Endmill.fctb", 6.0, "6mm Endmill", "TC_6mm", 800, 250, 10000),
    "em2": (4, "5mm_Endmill.fctb", 2.0, "2mm Endmill", "TC_2mm", 400, 150, 15000),
    "ball3": (5, "6mm_Ball_End.fctb", 3.0, "3mm Ball End", "TC_ball3", 800, 200, 14000),
}
OPTOOL = {"drill": "drill5", "dwell": "drill5", "peck": "drill5", "pocket": "em3",
          "adaptive": "em3", "profile": "em3", "pocketprofile": "em3", "surface": "ball3"}
OPTOOL.update(TOOLS)
# Job.Create may have made a default TC already; replace it by ours
for old in list(job.Tools.Group):
    job.Tools.removeObject(old)
tcs = {}
def tool(key):
    if key in tcs:
        return tcs[key]
    num, fctb, dia, label, name, feed, plunge, rpm = TOOLDEFS[key]
    bit = PathToolBit.Factory.CreateFrom(os.path.join(bitdir, fctb),
                                          "EndMill3" if key == "em3" else "Bit_" + key)
    bit.Diameter = dia
    bit.Label = label
    tc = PathToolController.Create(name, bit, num)
    tc.Label = "TC: " + label
    # Feeds are speed Quantities stored in mm/s: a bare float 600 means 600 mm/s (-> F36000).
    # Always give units explicitly.
    tc.HorizFeed = FreeCAD.Units.Quantity("%d mm/min" % feed)
    tc.VertFeed = FreeCAD.Units.Quantity("%d mm/min" % plunge)
    tc.SpindleSpeed = rpm
    tc.SpindleDir = "Forward"
    job.Proxy.addToolController(tc)
    doc.recompute()
    tcs[key] = tc
    return tc

model = job.Model.Group[0]   # the clone of `part` inside the job
# the pocket floor: planar face, normal +Z, at Z=5
floor = None
for i, f in enumerate(model.Shape.Faces):
    bb = f.BoundBox
    if abs(bb.ZMin - 5) < 1e-6 and abs(bb.ZMax - 5) < 1e-6:
        floor = "Face%d" % (i + 1)
print("pocket floor face:", floor)

def hole_faces(ztop):
    """the model's cylindrical 5 mm hole faces whose top is at ztop"""
    out = []
    for i, f in enumerate(model.Shape.Faces):
        if (f.Surface.__class__.__name__ == "Cylinder" and abs(f.Surface.Radius - 2.5) < 1e-6
                and abs(f.BoundBox.ZMax - ztop) < 1e-6):
            out.append("Face%d" % (i + 1))
    return out

# A new op takes a tool controller from PathUtils.findToolController: none in the job raises,
# more than one asks the GUI (PathUtils.UserInput), which headless is None -> UnboundLocalError.
# Stand in for the GUI: it answers with the tool controller of the op being created.
from PathScripts import PathUtils
class Chooser:
    wanted = None
    def selectedToolController(self):
        return self.wanted
    def chooseToolController(self, controllers):
        return self.wanted
chooser = Chooser()
PathUtils.UserInput = chooser
_tool = tool
def tool(key):
    chooser.wanted = _tool(key)
    return chooser.wanted

ops = []
for name, label in (("drill", "Drilling"), ("dwell", "DwellDrilling"), ("peck", "PeckDrilling")):
    if name not in OPS:
        continue
    # PathDrilling.Create would call findAllHoles, which needs the op's model, set only when the
    # op first executes (0.20 headless: 'NoneType' object is not iterable): do what Create does
    # without it, and name the holes ourselves.
    tool(OPTOOL[name])
    op = doc.addObject("Path::FeaturePython", label)
    op.Proxy = PathDrilling.ObjectDrilling(op, label, job)
    op.ToolController = tool(OPTOOL[name])
    faces = hole_faces(10) + hole_faces(5)
    op.Base = [(model, faces)]
    op.DwellEnabled = name == "dwell"
    op.DwellTime = 0.5          # s, G82's P
    op.PeckEnabled = name == "peck"
    op.setExpression("PeckDepth", None)   # default is bound to OpToolDiameter*0.75
    op.PeckDepth = 2.0          # mm, G83's Q
    if "starthole" in FEATURES and "holes" not in FEATURES:
        # a start hole for the pocket: drilled from above the stock top before the pocket is cut
        op.setExpression("StartDepth", None)
        op.StartDepth = 10.0
        op.setExpression("RetractHeight", None)
        op.RetractHeight = 11.0
    ops.append(op)
if "pocket" in OPS:
    tool(OPTOOL["pocket"])
    op = PathPocketShape.Create("Pocket", parentJob=job)
    op.Base = [(model, [floor])]
    op.ToolController = tool(OPTOOL["pocket"])
    op.StepOver = 50          # percent of tool diameter
    op.setExpression("StepDown", None)   # default is bound to OpToolDiameter and would override
    op.StepDown = 2.0         # mm per pass
    op.OffsetPattern = "ZigZag"
    ops.append(op)
if "adaptive" in OPS:
    tool(OPTOOL["adaptive"])
    op = PathAdaptive.Create("Adaptive", parentJob=job)
    op.Base = [(model, [floor])]
    op.ToolController = tool(OPTOOL["adaptive"])
    op.StepOver = 20
    op.OperationType = "Clearing"
    op.Side = "Inside"
    ops.append(op)
if "profile" in OPS:
    tool(OPTOOL["profile"])
    op = PathProfile.Create("Profile", parentJob=job)   # no Base -> outline of whole model
    op.ToolController = tool(OPTOOL["profile"])
    op.Side = "Outside"
    op.setExpression("StepDown", None)
    op.StepDown = 2.5
    op.processHoles = False
    op.processPerimeter = True
    ops.append(op)
if "pocketprofile" in OPS:
    # finish the pocket's walls: profile of the floor face's outline, inside, full depth
    tool(OPTOOL["pocketprofile"])
    op = PathProfile.Create("PocketProfile", parentJob=job)
    op.Base = [(model, [floor])]
    op.ToolController = tool(OPTOOL["pocketprofile"])
    op.Side = "Inside"
    op.setExpression("StepDown", None)
    op.StepDown = 2.5
    op.processHoles = False
    op.processPerimeter = True
    ops.append(op)
if "surface" in OPS:
    from PathScripts import PathSurface   # imports ocl
    tool(OPTOOL["surface"])
    op = PathSurface.Create("Surface", parentJob=job)   # no Base -> the whole model
    op.ToolController = tool(OPTOOL["surface"])
    op.ScanType = "Planar"
    op.LayerMode = "Single-pass"
    op.CutPattern = os.environ.get("SURFPATTERN", "Line")
    op.BoundBox = "Stock"
    # passes at 45 degrees to X cross the fillets and the pocket's walls obliquely: X, Y and Z
    # move together (at 0 the passes run along the fillets, at constant Z)
    op.CutPatternAngle = float(os.environ.get("SURFANGLE", "45"))
    op.StepOver = float(os.environ.get("SURFSTEP", "15"))            # percent of diameter
    op.SampleInterval = float(os.environ.get("SURFSAMPLE", "0.5"))   # mm along a pass
    ops.append(op)
doc.recompute()

for op in ops:
    print(op.Name, "commands:", len(op.Path.Commands),
          "StartDepth", op.StartDepth, "FinalDepth", op.FinalDepth,
          "ClearanceHeight", op.ClearanceHeight, "SafeHeight", op.SafeHeight)

# --- post list like PathPost.buildPostList (OrderOutputBy = Fixture, single G54)
class Fixture:  # stand-in for PathPost._TempObject (PathPost itself imports FreeCADGui)
    pass
fx = Fixture(); fx.Name = fx.Label = "G54"
fx.Path = Path.Path([Path.Command("G54"),
                     Path.Command("G0", {"Z": job.Stock.Shape.BoundBox.ZMax
                                         + job.SetupSheet.ClearanceHeightOffset.Value})])
postlist, cur = [fx], None
for op in job.Operations.Group:
    if not PathUtil.opProperty(op, "Active"):
        continue
    t = PathUtil.toolControllerForOp(op)
    if t is not None and t != cur:
        postlist.append(t); cur = t
    postlist.append(op)

post = PostProcessor.load("grbl")
POSTARGS = os.environ.get("POSTARGS", "--no-show-editor")   # add --no-header for reproducible output
post.export(postlist, OUT, POSTARGS)
print("wrote", OUT)
