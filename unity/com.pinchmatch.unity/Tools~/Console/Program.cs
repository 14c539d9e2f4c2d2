// pinchmatch-unity: the package's engine-free core on a result folder, from the command line (Mono
// or .NET). Given where each prop is tracked in Unity's world, it prints per match the virtual
// object's Unity pose and the Unity positions of its fingertip targets as JSON; given a hand path,
// the seen (warped) path. Documentation~/console.md has the options and an example.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.IO;

namespace Pinchmatch.Console
{
    public static class Program
    {
        const string Usage =
            "usage: pinchmatch-unity RESULT_DIR [--prop-pose [PROP=]X,Y,Z,QX,QY,QZ,QW]... " +
            "[--level-root X,Y,Z,QX,QY,QZ,QW] [--hand-path PATH.json]";

        public static int Main(string[] args)
        {
            try
            {
                System.Console.Out.WriteLine(Json.Write(Run(args)));
                return 0;
            }
            catch (Exception e) when (e is ArgumentException || e is JsonException || e is IOException
                                      || e is KeyNotFoundException || e is FormatException)
            {
                System.Console.Error.WriteLine("pinchmatch-unity: " + e.Message.Replace('\n', ' '));
                return 2;
            }
        }

        public static Dictionary<string, object> Run(string[] args)
        {
            string folder = null, handPath = null;
            var poses = new Dictionary<string, Pose>();
            Pose? every = null;
            var root = Pose.Identity;
            for (int i = 0; i < args.Length; i++)
            {
                string a = args[i];
                if (a == "--prop-pose" || a == "--level-root" || a == "--hand-path")
                {
                    if (i + 1 >= args.Length) throw new ArgumentException(a + " needs a value; " + Usage);
                    string v = args[++i];
                    if (a == "--hand-path") handPath = v;
                    else if (a == "--level-root") root = ParsePose(v, a);
                    else if (v.Contains("=")) poses[v.Substring(0, v.IndexOf('='))] = ParsePose(v.Substring(v.IndexOf('=') + 1), a);
                    else every = ParsePose(v, a);
                }
                else if (a.StartsWith("-")) throw new ArgumentException("unknown option " + a + "; " + Usage);
                else if (folder == null) folder = a;
                else throw new ArgumentException("one result folder, not two; " + Usage);
            }
            if (folder == null) throw new ArgumentException("no result folder; " + Usage);
            var file = MatchesFile.Load(Path.Combine(folder, "matches.json"));
            LevelFile level = null;
            if (file.Placement == "fixed")
            {
                string path = Path.Combine(folder, "level.glb");
                if (!File.Exists(path))
                    throw new IOException(folder + ": a --placement fixed result without level.glb; run the match with its default outputs");
                level = LevelFile.Load(path);
            }
            var matches = new List<object>();
            var placedByName = new Dictionary<string, Placed>();
            foreach (var m in file.Matches)
            {
                if (m.Best == null)
                {
                    matches.Add(new Dictionary<string, object> { { "virtual", m.Virtual }, { "tangible", null }, { "reason", m.Reason } });
                    continue;
                }
                Pose prop;
                if (!poses.TryGetValue(m.Best.Tangible, out prop))
                {
                    if (!every.HasValue)
                        throw new ArgumentException("no --prop-pose for the prop '" + m.Best.Tangible + "'");
                    prop = every.Value;
                }
                var placed = level != null ? Placement.OnLevelProp(file, level, m, prop, root)
                    : Placement.OnSceneProp(file, m, m.Best, prop);
                placedByName[m.Virtual] = placed;
                matches.Add(Record(placed));
            }
            var output = new Dictionary<string, object>
            {
                { "frame", "Unity: metres, left-handed, +Y up; rotations as quaternions x, y, z, w" },
                { "matches", matches },
            };
            var carousel = new Dictionary<string, object>();
            foreach (var t in file.Tangibles)
            {
                var names = new List<object>();
                foreach (int i in Carousel.Queue(file, t.Name)) names.Add(file.Matches[i].Virtual);
                if (names.Count > 0) carousel[t.Name] = names;
            }
            output["carousel"] = carousel;
            if (handPath != null) output["warped"] = Warped(handPath, placedByName);
            return output;
        }

        static Dictionary<string, object> Record(Placed p)
        {
            var r = new Dictionary<string, object>
            {
                { "virtual", p.Virtual }, { "tangible", p.Tangible }, { "mode", p.Mode }, { "cost", p.Cost },
                { "virtual_pose", PoseRecord(p.VirtualPose) },
                { "fingertips", TargetsRecord(p.Fingertips) },
                { "seen_fingertips", TargetsRecord(p.SeenFingertips) },
                { "pinch_center", p.PinchCenter.ToArray() },
                { "approach", p.Approach.HasValue ? p.Approach.Value.ToArray() : null },
                { "wrist", Placement.Wrist(p).HasValue ? Placement.Wrist(p).Value.ToArray() : null },
                { "xri_attach", PoseRecord(Toolkits.XriAttach(p)) },
            };
            if (p.Warped)
            {
                r["hand_start"] = p.HandStart.ToArray();
                r["physical_target"] = p.PhysicalTarget.ToArray();
                r["virtual_target"] = p.VirtualTarget.ToArray();
            }
            return r;
        }

        static Dictionary<string, object> PoseRecord(Pose pose)
        {
            return new Dictionary<string, object>
            {
                { "position", pose.Position.ToArray() }, { "rotation_xyzw", pose.Rotation.ToArray() },
            };
        }

        static Dictionary<string, object> TargetsRecord(Target[] targets)
        {
            var d = new Dictionary<string, object>();
            foreach (var t in targets) d[t.Joint] = t.Position.ToArray();
            return d;
        }

        /// <summary>The hand path {"virtual": NAME, "frames": [[[x, y, z] per fingertip] per frame]}
        /// (Unity's world, metres), each frame's fingertips as seen.</summary>
        static Dictionary<string, object> Warped(string path, Dictionary<string, Placed> placed)
        {
            if (!File.Exists(path)) throw new IOException("no hand path at " + path);
            var doc = JsonFields.Obj(Json.Parse(File.ReadAllText(path)), path);
            string name = JsonFields.Str(JsonFields.Get(doc, "virtual", path), path + ".virtual");
            Placed p;
            if (!placed.TryGetValue(name, out p)) throw new KeyNotFoundException(path + ": no match for '" + name + "'");
            var frames = new List<object>();
            foreach (var f in JsonFields.Arr(JsonFields.Get(doc, "frames", path), path + ".frames"))
            {
                var tips = JsonFields.Arr(f, path + ".frames[]");
                var real = new Vec3[tips.Count];
                for (int i = 0; i < real.Length; i++) real[i] = JsonFields.Vec(tips[i], path + ".frames[][]");
                var seen = Warp.Fingertips(p, real);
                var row = new List<object>();
                foreach (var s in seen) row.Add(s.ToArray());
                frames.Add(row);
            }
            return new Dictionary<string, object> { { "virtual", name }, { "mode", p.Mode }, { "frames", frames } };
        }

        static Pose ParsePose(string text, string option)
        {
            var parts = text.Split(',');
            if (parts.Length != 7)
                throw new ArgumentException(option + " " + text + ": give X,Y,Z,QX,QY,QZ,QW (metres, a unit quaternion)");
            var v = new double[7];
            for (int i = 0; i < 7; i++)
                if (!double.TryParse(parts[i], NumberStyles.Float, CultureInfo.InvariantCulture, out v[i]) || double.IsNaN(v[i]) || double.IsInfinity(v[i]))
                    throw new ArgumentException(option + " " + text + ": '" + parts[i] + "' is not a number");
            var q = new Quat(v[3], v[4], v[5], v[6]);
            if (Math.Abs(q.Norm - 1) > 1e-3)
                throw new ArgumentException(option + " " + text + ": the quaternion's length is " + q.Norm.ToString("G4", CultureInfo.InvariantCulture) + ", not 1");
            return new Pose(new Vec3(v[0], v[1], v[2]), q.Normalized);
        }
    }
}
