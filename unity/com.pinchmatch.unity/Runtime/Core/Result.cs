// A pinchmatch result as matches.json holds it (schema pinchmatch.matches/1), in pinchmatch's own
// frames: millimetres, each object's file frame. Placement.cs turns it into Unity's.
using System;
using System.Collections.Generic;
using System.IO;
using static Pinchmatch.JsonFields;

namespace Pinchmatch
{
    /// <summary>A prop or a virtual object of the run.</summary>
    public sealed class ObjectInfo
    {
        public string Name;
        /// <summary>The level node it came from (a level split into its nodes), else null.</summary>
        public string Node;
        /// <summary>Its up in its file frame (unit vector).</summary>
        public Vec3 Up;
    }

    /// <summary>Where the fingers go on one object: a pinch's two contacts (thumb, index) or a
    /// tripod's three (thumb, index, middle), mm, in the object's file frame.</summary>
    public sealed class Grasp
    {
        public Vec3[] ContactsMm;
        /// <summary>The outward unit normals at the contacts.</summary>
        public Vec3[] Normals;
        /// <summary>From the fingertips towards the hand (unit), or null where none clears.</summary>
        public Vec3? Approach;

        /// <summary>The fingertip pads' centres: each contact plus the radius along its normal.</summary>
        public Vec3[] PadsMm(double fingertipRadiusMm)
        {
            var pads = new Vec3[ContactsMm.Length];
            for (int i = 0; i < pads.Length; i++) pads[i] = ContactsMm[i] + Normals[i] * fingertipRadiusMm;
            return pads;
        }

        /// <summary>The contacts' mean.</summary>
        public Vec3 CenterMm { get { return Vec3.Centroid(ContactsMm); } }
    }

    /// <summary>One choice: a prop, the grasp on it and on the virtual object, and the transform
    /// that registers the virtual object on the prop.</summary>
    public sealed class Choice
    {
        public string Tangible;
        public double Cost;
        public Grasp OnTangible;
        public Grasp OnVirtual;
        /// <summary>x_T = R x_V + t: the virtual file frame (mm) into the prop's (mm), det +1.</summary>
        public Affine VirtualToTangibleMm;
    }

    /// <summary>Under --placement fixed: redirect (the object stays, the hand is warped) or carousel.</summary>
    public sealed class Redirection
    {
        public string Mode;
        public Vec3 HandStartMm, PhysicalTargetMm, VirtualTargetMm;
        public double AngleDeg;
    }

    /// <summary>One virtual object's result.</summary>
    public sealed class Match
    {
        public string Virtual;
        /// <summary>The best choice, or null (then Reason says why).</summary>
        public Choice Best;
        public List<Choice> Alternatives = new List<Choice>();
        public bool Noticeable;
        public string Reason;
        public Redirection Redirection;

        /// <summary>The best choice first, then the alternatives.</summary>
        public IEnumerable<Choice> Choices
        {
            get
            {
                if (Best == null) yield break;
                yield return Best;
                foreach (var c in Alternatives) yield return c;
            }
        }
    }

    /// <summary>matches.json.</summary>
    public sealed class MatchesFile
    {
        public const string Schema = "pinchmatch.matches/1";

        /// <summary>"pinch" or "tripod".</summary>
        public string GraspKind;
        public string Placement;
        public double FingertipRadiusMm;
        public List<ObjectInfo> Tangibles = new List<ObjectInfo>();
        public List<ObjectInfo> Virtuals = new List<ObjectInfo>();
        public List<Match> Matches = new List<Match>();

        public static MatchesFile Load(string path)
        {
            if (!File.Exists(path)) throw new FileNotFoundException("no matches.json at " + path +
                                            ": give the folder `pinchmatch match -o OUT` wrote", path);
            try
            {
                return Parse(File.ReadAllText(path));
            }
            catch (JsonException e)
            {
                throw new JsonException(path + ": " + e.Message);
            }
        }

        public static MatchesFile Parse(string text)
        {
            var doc = Obj(Json.Parse(text), "matches.json");
            var schema = Opt(doc, "schema") as string;
            if (schema != Schema)
                throw new JsonException("not a pinchmatch result: schema " + (schema ?? "missing") +
                                        ", expected " + Schema);
            var settings = Obj(Get(doc, "settings", "matches.json"), "settings");
            var file = new MatchesFile
            {
                GraspKind = (Opt(doc, "grasp") as string) ?? "pinch",
                Placement = (Opt(settings, "placement") as string) ?? "registered",
                FingertipRadiusMm = Num(Get(settings, "fingertip_radius_mm", "settings"),
                                        "settings.fingertip_radius_mm"),
            };
            foreach (var o in Arr(Get(doc, "tangibles", "matches.json"), "tangibles"))
                file.Tangibles.Add(ReadObject(Obj(o, "a tangible")));
            foreach (var o in Arr(Get(doc, "virtuals", "matches.json"), "virtuals"))
                file.Virtuals.Add(ReadObject(Obj(o, "a virtual object")));
            foreach (var m in Arr(Get(doc, "matches", "matches.json"), "matches"))
                file.Matches.Add(ReadMatch(Obj(m, "a match")));
            return file;
        }

        public ObjectInfo Tangible(string name)
        {
            foreach (var o in Tangibles) if (o.Name == name) return o;
            throw new KeyNotFoundException("no prop named '" + name + "' in the result");
        }

        public ObjectInfo Virtual(string name)
        {
            foreach (var o in Virtuals) if (o.Name == name) return o;
            throw new KeyNotFoundException("no virtual object named '" + name + "' in the result");
        }

        static ObjectInfo ReadObject(Dictionary<string, object> o)
        {
            string name = Str(Get(o, "name", "an object"), "name");
            return new ObjectInfo
            {
                Name = name,
                Node = Opt(o, "node") as string,
                Up = Vec(Get(o, "up_vector", name), name + ".up_vector"),
            };
        }

        static Match ReadMatch(Dictionary<string, object> m)
        {
            string name = Str(Get(m, "virtual", "a match"), "virtual");
            var match = new Match
            {
                Virtual = name,
                Reason = Opt(m, "reason") as string,
                Noticeable = Opt(m, "noticeable") is bool && (bool)Opt(m, "noticeable"),
            };
            if (Opt(m, "tangible") is string)
            {
                match.Best = ReadChoice(m, name);
                var alternatives = Opt(m, "alternatives") as List<object>;
                if (alternatives != null)
                    foreach (var a in alternatives)
                        match.Alternatives.Add(ReadChoice(Obj(a, name + ".alternatives"), name));
            }
            var r = Opt(m, "redirection") as Dictionary<string, object>;
            if (r != null)
            {
                string what = name + ".redirection";
                match.Redirection = new Redirection
                {
                    Mode = Str(Get(r, "mode", what), what + ".mode"),
                    HandStartMm = Vec(Get(r, "hand_start_mm", what), what + ".hand_start_mm"),
                    PhysicalTargetMm = Vec(Get(r, "physical_target_mm", what), what + ".physical_target_mm"),
                    VirtualTargetMm = Vec(Get(r, "virtual_target_mm", what), what + ".virtual_target_mm"),
                    AngleDeg = Opt(r, "angle_deg") is double ? (double)Opt(r, "angle_deg") : double.NaN,
                };
            }
            return match;
        }

        static Choice ReadChoice(Dictionary<string, object> c, string name)
        {
            var rows = Arr(Get(c, "transform_virtual_to_tangible", name), name + ".transform");
            var flat = new double[16];
            for (int i = 0; i < 4; i++)
            {
                var row = Nums(rows[i], name + ".transform[" + i + "]", 4);
                Array.Copy(row, 0, flat, 4 * i, 4);
            }
            return new Choice
            {
                Tangible = Str(Get(c, "tangible", name), name + ".tangible"),
                Cost = Num(Get(c, "cost", name), name + ".cost"),
                OnTangible = ReadGrasp(Obj(Get(c, "tangible_pose", name), name + ".tangible_pose"),
                                       name + ".tangible_pose"),
                OnVirtual = ReadGrasp(Obj(Get(c, "virtual_pose", name), name + ".virtual_pose"),
                                      name + ".virtual_pose"),
                VirtualToTangibleMm = Affine.FromRowMajor(flat),
            };
        }

        /// <summary>A pose record: a tripod's contacts_mm and normals, or a pinch's p1_mm, p2_mm,
        /// n1 and n2.</summary>
        static Grasp ReadGrasp(Dictionary<string, object> p, string what)
        {
            Vec3[] contacts, normals;
            if (Opt(p, "contacts_mm") != null)
            {
                contacts = Vectors(Arr(p["contacts_mm"], what + ".contacts_mm"), what + ".contacts_mm");
                normals = Vectors(Arr(Get(p, "normals", what), what + ".normals"), what + ".normals");
            }
            else
            {
                contacts = new[] { Vec(Get(p, "p1_mm", what), what + ".p1_mm"),
                                   Vec(Get(p, "p2_mm", what), what + ".p2_mm") };
                normals = new[] { Vec(Get(p, "n1", what), what + ".n1"), Vec(Get(p, "n2", what), what + ".n2") };
            }
            if (contacts.Length != normals.Length)
                throw new JsonException(what + " has " + contacts.Length + " contacts but " +
                                        normals.Length + " normals");
            var approach = Opt(p, "approach");
            return new Grasp
            {
                ContactsMm = contacts,
                Normals = normals,
                Approach = approach == null ? (Vec3?)null : Vec(approach, what + ".approach"),
            };
        }

        static Vec3[] Vectors(List<object> list, string what)
        {
            var out_ = new Vec3[list.Count];
            for (int i = 0; i < list.Count; i++) out_[i] = Vec(list[i], what + "[" + i + "]");
            return out_;
        }
    }
}
