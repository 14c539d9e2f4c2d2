using System;
using System.Collections.Generic;
using System.Text;
using NUnit.Framework;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    /// <summary>A level as level.glb writes it: a redirected cup, a jar the carousel brings onto the
    /// prop, the prop's node turned about two axes off the origin.</summary>
    [TestFixture]
    public class LevelTests
    {
        static readonly Quat PropTurn = (Quat.AxisAngle(new Vec3(0, 1, 0), 35) * Quat.AxisAngle(new Vec3(1, 0, 0), -90)).Normalized;
        static readonly Vec3 PropAt = new Vec3(0.5, 0.9, -0.25);

        static List<object> Column(Affine m)
        {
            var A = m.A;
            return Fixtures.L(A.M00, A.M10, A.M20, 0.0, A.M01, A.M11, A.M21, 0.0, A.M02, A.M12, A.M22, 0.0,
                              m.T.X, m.T.Y, m.T.Z, 1.0);
        }

        static Dictionary<string, object> Extras(params object[] kv)
        {
            return Fixtures.Obj("pinchmatch", Fixtures.Obj(kv));
        }

        static Dictionary<string, object> MatchExtras(string mode, string carouselNode)
        {
            var e = Fixtures.Obj("mode", mode, "prop", "prop",
                                 "virtual_contacts_m", Fixtures.L(0.51, 0.93, -0.22, 0.52, 0.94, -0.27),
                                 "physical_contacts_m", Fixtures.L(0.49, 0.94, -0.22, 0.51, 0.94, -0.27),
                                 "virtual_target_m", Fixtures.L(0.515, 0.935, -0.245),
                                 "physical_target_m", Fixtures.L(0.50, 0.94, -0.245),
                                 "hand_start_m", Fixtures.L(0.5, 1.05, 0.05));
            if (carouselNode != null) e["carousel_node"] = carouselNode;
            return Fixtures.Obj("pinchmatch", e);
        }

        static readonly Affine CupWorld = Affine.Trs(new Vec3(0.52, 0.9, -0.25), Quat.AxisAngle(new Vec3(0, 1, 0), 20), new Vec3(1, 1, 1));
        static readonly Affine CarouselLocal = new Affine(Mat3.Of(Quat.AxisAngle(new Vec3(1, 2, 3), 40)), new Vec3(0.001, 0.03, -0.002));

        public static string LevelJson(bool withSchema = true, bool withCarouselNode = true)
        {
            var nodes = Fixtures.L(
                Fixtures.Obj("name", "cup", "matrix", Column(CupWorld), "children", Fixtures.L(2.0, 3.0),
                             "extras", MatchExtras("redirect", null)),
                Fixtures.Obj("name", "pinchmatch_prop_prop", "translation", Fixtures.V(PropAt),
                             "rotation", Fixtures.L(PropTurn.X, PropTurn.Y, PropTurn.Z, PropTurn.W),
                             "children", Fixtures.L(4.0),
                             "extras", Extras("role", "prop", "name", "prop")),
                Fixtures.Obj("name", "thumb_tip", "translation", Fixtures.L(0.01, 0.03, 0.033), "extras", Extras("role", "joint")),
                Fixtures.Obj("name", "index_tip", "translation", Fixtures.L(-0.004, 0.024, -0.033), "extras", Extras("role", "joint")),
                Fixtures.Obj("name", "carousel_jar", "matrix", Column(CarouselLocal), "children", Fixtures.L(5.0, 6.0),
                             "extras", Extras("role", "carousel", "node", "jar", "prop", "prop")),
                Fixtures.Obj("name", "thumb_tip", "translation", Fixtures.L(-0.016, 0.054, 0.031), "extras", Extras("role", "joint")),
                Fixtures.Obj("name", "index_tip", "translation", Fixtures.L(-0.017, 0.053, -0.030), "extras", Extras("role", "joint")),
                Fixtures.Obj("name", "jar", "translation", Fixtures.L(0.9, 0.9, -0.5), "extras", MatchExtras("carousel", withCarouselNode ? "carousel_jar" : "carousel_lost")));
            var scene = Fixtures.Obj("nodes", Fixtures.L(0.0, 1.0, 7.0));
            if (withSchema)
                scene["extras"] = Extras("schema", "pinchmatch.level/2", "settings", Fixtures.Obj("fingertip_radius_mm", 8.0));
            return Json.Write(Fixtures.Obj("asset", Fixtures.Obj("version", "2.0"), "scene", 0.0,
                                           "scenes", Fixtures.L(scene), "nodes", nodes));
        }

        static MatchesFile Matches()
        {
            var cup = Fixtures.Choice(Fixtures.Pinch, PropTurn, Vec3.Zero, 0.6);
            var jar = Fixtures.Choice(Fixtures.Pinch, Quat.Identity, new Vec3(1, 2, 3), 0.2);
            cup["virtual"] = "cup";
            jar["virtual"] = "jar";
            cup["redirection"] = Fixtures.Obj("mode", "redirect", "hand_start_mm", Fixtures.L(500.0, 1050.0, 50.0),
                                              "physical_target_mm", Fixtures.L(500.0, 940.0, -245.0),
                                              "virtual_target_mm", Fixtures.L(515.0, 935.0, -245.0), "angle_deg", 2.7);
            jar["redirection"] = Fixtures.Obj("mode", "carousel", "hand_start_mm", Fixtures.L(500.0, 1050.0, 50.0),
                                              "physical_target_mm", Fixtures.L(500.0, 940.0, -245.0),
                                              "virtual_target_mm", Fixtures.L(900.0, 950.0, -500.0));
            return MatchesFile.Parse(Json.Write(Fixtures.Obj(
                "schema", "pinchmatch.matches/1", "settings", Fixtures.Obj("fingertip_radius_mm", 8.0, "placement", "fixed"),
                "tangibles", Fixtures.L(Fixtures.Obj("name", "prop", "up_vector", Fixtures.V(Fixtures.ZUp))),
                "virtuals", Fixtures.L(Fixtures.Obj("name", "cup", "node", "cup", "up_vector", Fixtures.V(Fixtures.YUp)),
                                       Fixtures.Obj("name", "jar", "node", "jar", "up_vector", Fixtures.V(Fixtures.YUp))),
                "matches", Fixtures.L(cup, jar))));
        }

        /// <summary>The prop's node as the level has it, seen in Unity (the level at the origin).</summary>
        static Pose PropInUnity()
        {
            return Frames.GltfToUnity(new Pose(PropAt, PropTurn));
        }

        public static byte[] Glb(string json)
        {
            var text = Encoding.UTF8.GetBytes(json);
            int padded = (text.Length + 3) / 4 * 4;
            var data = new byte[20 + padded];
            Encoding.ASCII.GetBytes("glTF").CopyTo(data, 0);
            BitConverter.GetBytes(2u).CopyTo(data, 4);
            BitConverter.GetBytes((uint)data.Length).CopyTo(data, 8);
            BitConverter.GetBytes((uint)padded).CopyTo(data, 12);
            BitConverter.GetBytes(0x4E4F534Au).CopyTo(data, 16);
            for (int i = 0; i < padded; i++) data[20 + i] = i < text.Length ? text[i] : (byte)' ';
            return data;
        }

        [Test]
        public void TheGlbsJsonChunkIsRead()
        {
            var level = LevelFile.Parse(LevelFile.GlbJson(Glb(LevelJson())));
            Assert.AreEqual(2, level.Matches.Count);
            Assert.IsTrue(level.Props.ContainsKey("prop"));
            Assert.AreEqual(8.0, level.FingertipRadiusMm);
        }

        [Test]
        public void AFileThatIsNotAGlbIsNamed()
        {
            var bytes = Glb(LevelJson());
            bytes[0] = (byte)'x';
            Assert.Throws<JsonException>(() => LevelFile.GlbJson(bytes));
            var truncated = new byte[30];
            Array.Copy(Glb(LevelJson()), truncated, 30);
            Assert.Throws<JsonException>(() => LevelFile.GlbJson(truncated));
        }

        [Test]
        public void ALevelWithoutPinchmatchsSchemaIsRefused()
        {
            var e = Assert.Throws<JsonException>(() => LevelFile.Parse(LevelJson(withSchema: false)));
            StringAssert.Contains("pinchmatch.level/2", e.Message);
            Assert.Throws<JsonException>(() => LevelFile.Parse(LevelJson(withCarouselNode: false)));
        }

        [Test]
        public void ChildrenAreHeldInTheirParentsFrame()
        {
            var level = LevelFile.Parse(LevelJson());
            var cup = level.Match("cup");
            var thumb = cup.Joints["thumb_tip"];
            Fixtures.Near(CupWorld.Point(new Vec3(0.01, 0.03, 0.033)), thumb.World.T, 1e-15);
            var carousel = level.Match("jar").CarouselNode;
            var prop = Affine.Trs(PropAt, PropTurn, new Vec3(1, 1, 1));
            Fixtures.Near((prop * CarouselLocal).T, carousel.World.T, 1e-15);
        }

        [TestCase(0.0, 0.0)]
        [TestCase(60.0, -25.0)]
        public void TheCarouselsObjectRidesOnTheTrackedProp(double a, double b)
        {
            var level = LevelFile.Parse(LevelJson());
            var file = Matches();
            var move = new Pose(new Vec3(0.3, -0.1, 0.7), Quat.AxisAngle(new Vec3(0.3, 1, 0.2), a + b));
            var tracked = move * PropInUnity();
            var placed = Placement.OnLevelProp(file, level, file.Matches[1], tracked, Pose.Identity);
            Assert.AreEqual("carousel", placed.Mode);
            // where the level has the prop, a point of the jar is the level's, mirrored
            var u = new Vec3(0.01, 0.02, -0.03);
            var inLevel = Frames.GltfToUnity(level.Match("jar").CarouselNode.World.Point(u));
            Fixtures.Near(move.Point(inLevel), placed.VirtualPose.Point(Frames.GltfToUnity(u)), 1e-12);
            CollectionAssert.AreEqual(placed.Fingertips, placed.SeenFingertips);
        }

        [Test]
        public void ARedirectedObjectStaysAndTheHandIsLedToTheProp()
        {
            var level = LevelFile.Parse(LevelJson());
            var file = Matches();
            var placed = Placement.OnLevelProp(file, level, file.Matches[0], PropInUnity(), Pose.Identity);
            Assert.IsTrue(placed.Warped);
            Fixtures.Near(Frames.GltfToUnity(CupWorld.T), placed.VirtualPose.Position, 1e-15);
            Fixtures.Near(Frames.GltfToUnity(new Vec3(0.50, 0.94, -0.245)), placed.PhysicalTarget, 1e-12);
            Fixtures.Near(Frames.GltfToUnity(new Vec3(0.515, 0.935, -0.245)), placed.VirtualTarget, 1e-15);
            Fixtures.Near(Frames.GltfToUnity(new Vec3(0.5, 1.05, 0.05)), placed.HandStart, 1e-15);
            Fixtures.Near(Frames.GltfToUnity(level.Match("cup").Joints["index_tip"].World.T),
                          placed.SeenFingertips[1].Position, 1e-15);
            Assert.AreEqual(Joints.IndexTip, placed.SeenFingertips[1].Joint);
        }

        [Test]
        public void ThePhysicalTargetMovesWithTheTrackedPropTheLevelStays()
        {
            var level = LevelFile.Parse(LevelJson());
            var file = Matches();
            var move = new Pose(new Vec3(-0.2, 0.05, 0.4), Quat.AxisAngle(new Vec3(0, 1, 0), 70));
            var home = Placement.OnLevelProp(file, level, file.Matches[0], PropInUnity(), Pose.Identity);
            var moved = Placement.OnLevelProp(file, level, file.Matches[0], move * PropInUnity(), Pose.Identity);
            Fixtures.Near(move.Point(home.PhysicalTarget), moved.PhysicalTarget, 1e-12);
            Fixtures.Near(move.Point(home.Fingertips[0].Position), moved.Fingertips[0].Position, 1e-12);
            Fixtures.Near(home.VirtualTarget, moved.VirtualTarget, 0);
            Fixtures.Near(home.HandStart, moved.HandStart, 0);
        }

        [Test]
        public void TheLevelsRootMovesWhatStaysInTheLevel()
        {
            var level = LevelFile.Parse(LevelJson());
            var file = Matches();
            var root = new Pose(new Vec3(1, 0, -2), Quat.AxisAngle(new Vec3(0, 1, 0), -90));
            var placed = Placement.OnLevelProp(file, level, file.Matches[0], root * PropInUnity(), root);
            var home = Placement.OnLevelProp(file, level, file.Matches[0], PropInUnity(), Pose.Identity);
            Fixtures.Near(root.Point(home.VirtualTarget), placed.VirtualTarget, 1e-12);
            Fixtures.Near(root.Point(home.PhysicalTarget), placed.PhysicalTarget, 1e-12);
            Fixtures.Near(root.Point(home.HandStart), placed.HandStart, 1e-12);
        }
    }
}
