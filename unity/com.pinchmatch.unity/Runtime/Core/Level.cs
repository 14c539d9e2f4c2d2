// OUT/level.glb (schema pinchmatch.level/2): the level as an engine loads it, with a node per prop,
// the carousel's objects below their prop, the fingers' joints below every matched node and
// pinchmatch's extras on each. Read from the GLB's JSON chunk only (the meshes are the importer's).
using System;
using System.Collections.Generic;
using System.IO;
using System.Text;
using static Pinchmatch.JsonFields;

namespace Pinchmatch
{
    /// <summary>A node of the level: its name, parent, local and world maps (glTF's frame, metres)
    /// and pinchmatch's extras (null where it has none).</summary>
    public sealed class LevelNode
    {
        public int Index;
        public string Name;
        public int Parent = -1;
        public List<int> Children = new List<int>();
        public Affine Local = Affine.Identity;
        public Affine World = Affine.Identity;
        public Dictionary<string, object> Extras;

        public string Role { get { return Extras == null ? null : Opt(Extras, "role") as string; } }
    }

    /// <summary>A matched node's record: its mode, prop and targets, in the level's frame (metres, as
    /// the glTF file has it).</summary>
    public sealed class LevelMatch
    {
        public LevelNode Node;
        public string Mode;
        public string Prop;
        /// <summary>The carousel's node below the prop's (mode carousel), else null.</summary>
        public LevelNode CarouselNode;
        public Vec3[] VirtualContactsM, PhysicalContactsM;
        public Vec3 VirtualTargetM, PhysicalTargetM, HandStartM;

        /// <summary>The joints (thumb_tip, index_tip, middle_tip, pinch_center, wrist) below the node
        /// that is pinched: the carousel's under mode carousel, the level's own under redirect.</summary>
        public Dictionary<string, LevelNode> Joints = new Dictionary<string, LevelNode>();
    }

    public sealed class LevelFile
    {
        public const string Schema = "pinchmatch.level/2";

        public List<LevelNode> Nodes = new List<LevelNode>();
        public Dictionary<string, LevelNode> Props = new Dictionary<string, LevelNode>();
        public List<LevelMatch> Matches = new List<LevelMatch>();
        public double FingertipRadiusMm;

        /// <summary>The JSON chunk of a GLB file (binary glTF 2.0).</summary>
        public static string GlbJson(byte[] data)
        {
            if (data.Length < 20 || Encoding.ASCII.GetString(data, 0, 4) != "glTF")
                throw new JsonException("not a GLB file (no 'glTF' magic)");
            if (BitConverter.ToUInt32(data, 4) != 2) throw new JsonException("not glTF 2.0");
            long total = BitConverter.ToUInt32(data, 8);
            if (total > data.Length) throw new JsonException("a truncated GLB file");
            long length = BitConverter.ToUInt32(data, 12);
            if (BitConverter.ToUInt32(data, 16) != 0x4E4F534A || 20 + length > data.Length)
                throw new JsonException("a GLB file whose first chunk is not JSON");
            return Encoding.UTF8.GetString(data, 20, (int)length);
        }

        public static LevelFile Load(string path)
        {
            if (!File.Exists(path)) throw new FileNotFoundException("no level at " + path, path);
            try
            {
                return Parse(GlbJson(File.ReadAllBytes(path)));
            }
            catch (JsonException e)
            {
                throw new JsonException(path + ": " + e.Message);
            }
        }

        public static LevelFile Parse(string json)
        {
            var doc = Obj(Json.Parse(json), "level.glb");
            var level = new LevelFile();
            var nodes = Opt(doc, "nodes") as List<object> ?? new List<object>();
            for (int i = 0; i < nodes.Count; i++)
                level.Nodes.Add(ReadNode(Obj(nodes[i], "node " + i), i));
            foreach (var n in level.Nodes)
                foreach (int c in n.Children)
                {
                    if (c < 0 || c >= level.Nodes.Count) throw new JsonException("node " + n.Index + " has a bad child " + c);
                    level.Nodes[c].Parent = n.Index;
                }
            foreach (var n in level.Nodes) if (n.Parent < 0) level.Place(n, Affine.Identity, 0);
            var scene = SceneExtras(doc);
            if (scene == null || Opt(scene, "schema") as string != Schema)
                throw new JsonException("not a pinchmatch level: its scene has no extras.pinchmatch.schema " + Schema);
            var settings = Opt(scene, "settings") as Dictionary<string, object>;
            level.FingertipRadiusMm = settings != null && Opt(settings, "fingertip_radius_mm") is double
                ? (double)settings["fingertip_radius_mm"] : 8.0;
            foreach (var n in level.Nodes)
                if (n.Role == "prop") level.Props[Str(Get(n.Extras, "name", n.Name), n.Name + ".name")] = n;
            foreach (var n in level.Nodes)
                if (n.Extras != null && Opt(n.Extras, "mode") is string) level.Matches.Add(level.ReadMatch(n));
            return level;
        }

        public LevelMatch Match(string node)
        {
            foreach (var m in Matches) if (m.Node.Name == node) return m;
            throw new KeyNotFoundException("no matched node '" + node + "' in the level");
        }

        void Place(LevelNode n, Affine parent, int depth)
        {
            if (depth > Nodes.Count) throw new JsonException("the level's nodes form a cycle");
            n.World = parent * n.Local;
            foreach (int c in n.Children) Place(Nodes[c], n.World, depth + 1);
        }

        static Dictionary<string, object> SceneExtras(Dictionary<string, object> doc)
        {
            var scenes = Opt(doc, "scenes") as List<object>;
            if (scenes == null || scenes.Count == 0) return null;
            int at = Opt(doc, "scene") is double ? (int)(double)doc["scene"] : 0;
            var extras = Opt(Obj(scenes[at], "scene"), "extras") as Dictionary<string, object>;
            return extras == null ? null : Opt(extras, "pinchmatch") as Dictionary<string, object>;
        }

        static LevelNode ReadNode(Dictionary<string, object> o, int index)
        {
            var n = new LevelNode { Index = index, Name = Opt(o, "name") as string ?? "" };
            var children = Opt(o, "children") as List<object>;
            if (children != null) foreach (var c in children) n.Children.Add((int)Num(c, "a child"));
            if (Opt(o, "matrix") != null)
                n.Local = Affine.FromColumnMajor(Nums(o["matrix"], n.Name + ".matrix", 16));
            else
            {
                var t = Opt(o, "translation") != null ? Vec(o["translation"], n.Name + ".translation") : Vec3.Zero;
                var r = Opt(o, "rotation") != null ? Nums(o["rotation"], n.Name + ".rotation", 4)
                    : new double[] { 0, 0, 0, 1 };
                var s = Opt(o, "scale") != null ? Vec(o["scale"], n.Name + ".scale") : new Vec3(1, 1, 1);
                n.Local = Affine.Trs(t, new Quat(r[0], r[1], r[2], r[3]).Normalized, s);
            }
            var extras = Opt(o, "extras") as Dictionary<string, object>;
            n.Extras = extras == null ? null : Opt(extras, "pinchmatch") as Dictionary<string, object>;
            return n;
        }

        LevelMatch ReadMatch(LevelNode n)
        {
            string what = n.Name + ".extras.pinchmatch";
            var e = n.Extras;
            var m = new LevelMatch
            {
                Node = n,
                Mode = Str(e["mode"], what + ".mode"),
                Prop = Str(Get(e, "prop", what), what + ".prop"),
                VirtualContactsM = Points(Get(e, "virtual_contacts_m", what), what + ".virtual_contacts_m"),
                PhysicalContactsM = Points(Get(e, "physical_contacts_m", what), what + ".physical_contacts_m"),
                VirtualTargetM = Vec(Get(e, "virtual_target_m", what), what + ".virtual_target_m"),
                PhysicalTargetM = Vec(Get(e, "physical_target_m", what), what + ".physical_target_m"),
                HandStartM = Vec(Get(e, "hand_start_m", what), what + ".hand_start_m"),
            };
            var holder = n;
            if (m.Mode == "carousel")
            {
                string name = Str(Get(e, "carousel_node", what), what + ".carousel_node");
                holder = Nodes.Find(x => x.Name == name && x.Role == "carousel");
                if (holder == null) throw new JsonException(what + " names a carousel node '" + name + "' the level lacks");
                m.CarouselNode = holder;
            }
            foreach (int c in holder.Children)
                if (Nodes[c].Role == "joint") m.Joints[Nodes[c].Name] = Nodes[c];
            return m;
        }

        static Vec3[] Points(object value, string what)
        {
            var flat = Nums(value, what, -1);
            if (flat.Length % 3 != 0) throw new JsonException(what + " is not a list of points");
            var out_ = new Vec3[flat.Length / 3];
            for (int i = 0; i < out_.Length; i++) out_[i] = new Vec3(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
            return out_;
        }
    }
}
