# FreeCAD 0.20 headless CAM (Path) job -> grbl G-code.
# Run:  OUT=pocket.nc OPS=pocket,profile POSTARGS="--no-show-editor --no-header" freecadcmd make_job.py
# Env:  OUT=/path/out.nc (default pocket.nc), OPS=pocket,profile,adaptive (comma list),
#       POSTARGS="--no-show-editor --no-header" (grbl_post args; --no-header drops the timestamp)
import os, sys
import FreeCAD, Part, Path
from PathScripts import PathJob, PathToolBit, PathToolController
from PathScripts import PathPocketShape, PathProfile, PathAdaptive, PathUtil
from PathScripts.PathPostProcessor import PostProcessor

OUT = os.environ.get("OUT", "pocket.nc")
OPS = os.environ.get("OPS", "pocket,profile").split(",")

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

# --- job (clones the model, creates Stock + SetupSheet)
job = PathJob.Create("Job", [part])
job.PostProcessor = "grbl"
job.PostProcessorArgs = "--no-show-editor"
job.PostProcessorOutputFile = OUT
# default stock = model bbox + 1 mm on every side; make stock == model bbox
for ext in ("ExtXneg", "ExtXpos", "ExtYneg", "ExtYpos", "ExtZneg", "ExtZpos"):
    setattr(job.Stock, ext, 0.0)
doc.recompute()

# --- tool: 3 mm flat end mill from the shipped endmill shape
bitdir = os.path.join(FreeCAD.getResourceDir(), "Mod/Path/Tools/Bit")
bit = PathToolBit.Factory.CreateFrom(os.path.join(bitdir, "5mm_Endmill.fctb"), "EndMill3")
bit.Diameter = 3.0
bit.Label = "3mm Endmill"
tc = PathToolController.Create("TC_3mm", bit, 1)
tc.Label = "TC: 3mm Endmill"
# Feeds are speed Quantities stored in mm/s: a bare float 600 means 600 mm/s (-> F36000).
# Always give units explicitly.
tc.HorizFeed = FreeCAD.Units.Quantity("600 mm/min")
tc.VertFeed = FreeCAD.Units.Quantity("200 mm/min")
tc.SpindleSpeed = 12000
tc.SpindleDir = "Forward"
# Job.Create may have made a default TC already; replace it by ours
for old in list(job.Tools.Group):
    job.Tools.removeObject(old)
job.Proxy.addToolController(tc)
doc.recompute()

model = job.Model.Group[0]   # the clone of `part` inside the job
# the pocket floor: planar face, normal +Z, at Z=5
floor = None
for i, f in enumerate(model.Shape.Faces):
    bb = f.BoundBox
    if abs(bb.ZMin - 5) < 1e-6 and abs(bb.ZMax - 5) < 1e-6:
        floor = "Face%d" % (i + 1)
print("pocket floor face:", floor)

ops = []
if "pocket" in OPS:
    op = PathPocketShape.Create("Pocket", parentJob=job)
    op.Base = [(model, [floor])]
    op.ToolController = tc
    op.StepOver = 50          # percent of tool diameter
    op.setExpression("StepDown", None)   # default is bound to OpToolDiameter and would override
    op.StepDown = 2.0         # mm per pass
    op.OffsetPattern = "ZigZag"
    ops.append(op)
if "adaptive" in OPS:
    op = PathAdaptive.Create("Adaptive", parentJob=job)
    op.Base = [(model, [floor])]
    op.ToolController = tc
    op.StepOver = 20
    op.OperationType = "Clearing"
    op.Side = "Inside"
    ops.append(op)
if "profile" in OPS:
    op = PathProfile.Create("Profile", parentJob=job)   # no Base -> outline of whole model
    op.ToolController = tc
    op.Side = "Outside"
    op.setExpression("StepDown", None)
    op.StepDown = 2.5
    op.processHoles = False
    op.processPerimeter = True
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
