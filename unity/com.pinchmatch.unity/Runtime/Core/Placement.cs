// A result placed in Unity's world: the virtual object's pose on the tracked prop, where each
// fingertip goes (named as OpenXR's and XR Hands' joints), the hand's approach, and under
// --placement fixed the targets of the hand's warp. Every position is Unity's (metres,
// left-handed, +Y up); Frames.cs says how pinchmatch's frames map there.
using System;
using System.Collections.Generic;

namespace Pinchmatch
{
    /// <summary>XR Hands' joint names (XRHandJointID) of a grasp's fingertips, in pinchmatch's finger
    /// order: thumb, index, middle.</summary>
    public static class Joints
    {
        public const string ThumbTip = "ThumbTip", IndexTip = "IndexTip", MiddleTip = "MiddleTip";
        public const string Wrist = "Wrist", PinchCenter = "PinchCenter";
        public static readonly string[] Fingertips = { ThumbTip, IndexTip, MiddleTip };
        /// <summary>level.glb's node names of the same joints.</summary>
        public static readonly string[] LevelNames = { "thumb_tip", "index_tip", "middle_tip" };
        /// <summary>How far the wrist is from the pinch's centre along the approach (mm), as
        /// level.glb places its wrist node.</summary>
        public const double WristMm = 110.0;
    }

    /// <summary>A named point in Unity's world (metres).</summary>
    public struct Target
    {
        public string Joint;
        public Vec3 Position;

        public Target(string joint, Vec3 position) { Joint = joint; Position = position; }
    }

    /// <summary>One choice in Unity's world.</summary>
    public sealed class Placed
    {
        public string Virtual, Tangible;
        public double Cost;
        /// <summary>"registered" (the object is shown on the prop), "carousel" (the same, brought by
        /// the carousel) or "redirect" (it stays where the level has it; the hand is warped).</summary>
        public string Mode;
        /// <summary>The pose of the virtual object's mesh frame (see the Placement methods).</summary>
        public Pose VirtualPose;
        /// <summary>The fingertip pads' centres on the prop: ThumbTip, IndexTip (and MiddleTip).</summary>
        public Target[] Fingertips;
        /// <summary>The contacts' mean on the prop.</summary>
        public Vec3 PinchCenter;
        /// <summary>From the fingertips towards the hand (unit), or null where none clears.</summary>
        public Vec3? Approach;
        /// <summary>Where the fingertips are seen: on the prop (registered, carousel) or on the
        /// level's object (redirect).</summary>
        public Target[] SeenFingertips;
        /// <summary>The warp's start, its physical and its virtual target (redirect only; the
        /// targets are the contacts' means).</summary>
        public Vec3 HandStart, PhysicalTarget, VirtualTarget;

        public bool Warped { get { return Mode == "redirect"; } }

        /// <summary>The fingertip positions alone, in finger order.</summary>
        public Vec3[] FingertipPositions { get { return Positions(Fingertips); } }

        public Vec3[] SeenFingertipPositions { get { return Positions(SeenFingertips); } }

        static Vec3[] Positions(Target[] targets)
        {
            var p = new Vec3[targets.Length];
            for (int i = 0; i < p.Length; i++) p[i] = targets[i].Position;
            return p;
        }
    }

    public static class Placement
    {
        /// <summary>A choice on a prop whose anchor is a match scene's <c>tangible</c> node (the
        /// scene imported with glTFast or UnityGLTF, or the prop's mesh imported from that scene),
        /// the anchor at <paramref name="prop"/> in Unity's world. The virtual pose is that of the
        /// scene's <c>virtual</c> node's mesh frame.</summary>
        public static Placed OnSceneProp(MatchesFile file, Match match, Choice choice, Pose prop)
        {
            var B = Frames.FileMmToUnity(file.Tangible(choice.Tangible).Up);
            return OnProp(file, match, choice, prop, B, B, "registered");
        }

        /// <summary>A choice on a prop, the prop's mesh mapped from its file's mm into the anchor's
        /// frame by <paramref name="propMesh"/> and the virtual object's by
        /// <paramref name="virtualMesh"/> (both as Frames.FileMmToUnity gives them for a glTF
        /// import; the virtual pose is then that of the virtual mesh's frame).</summary>
        public static Placed OnProp(MatchesFile file, Match match, Choice choice, Pose prop,
                                    Affine propMesh, Affine virtualMesh, string mode)
        {
            var P = Affine.Of(prop);
            var toWorld = P * propMesh;
            var virtualPose = Pose.Of(toWorld * choice.VirtualToTangibleMm * virtualMesh.Inverse);
            var placed = Fingers(file, choice, toWorld);
            placed.Virtual = match.Virtual;
            placed.Mode = mode;
            placed.VirtualPose = virtualPose;
            placed.SeenFingertips = placed.Fingertips;
            return placed;
        }

        /// <summary>A choice of a --placement fixed result whose prop is the level's
        /// <c>pinchmatch_prop_NAME</c> node, tracked at <paramref name="prop"/>, the level's root at
        /// <paramref name="levelRoot"/> (identity: the level imported at the origin). A carousel
        /// object's pose is that of the level's <c>carousel_NODE</c> node (its mesh the level node's
        /// own); a redirected object stays where the level has it (its node's world pose), and the
        /// warp's targets are set: the start and the virtual target in the level, the physical one
        /// on the tracked prop.</summary>
        public static Placed OnLevelProp(MatchesFile file, LevelFile level, Match match, Pose prop,
                                         Pose levelRoot)
        {
            if (match.Best == null) throw new ArgumentException(match.Virtual + " has no match: " + match.Reason);
            var lm = level.Match(match.Virtual);
            LevelNode propNode;
            if (!level.Props.TryGetValue(lm.Prop, out propNode))
                throw new KeyNotFoundException("the level has no node for the prop '" + lm.Prop + "'");
            var P = Affine.Of(prop);
            var root = Affine.Of(levelRoot);
            var S = Frames.GltfToUnityMap;
            // the prop node's frame holds the prop's mesh in its file frame, metres
            var toWorld = P * S * new Affine(Mat3.Scale(0.001), Vec3.Zero);
            var placed = Fingers(file, match.Best, toWorld);
            placed.Virtual = match.Virtual;
            placed.Mode = lm.Mode;
            if (lm.Mode == "carousel")
            {
                placed.VirtualPose = Pose.Of(P * S * lm.CarouselNode.Local * S);
                placed.SeenFingertips = placed.Fingertips;
                return placed;
            }
            var levelToWorld = root * S;
            placed.VirtualPose = Pose.Of(levelToWorld * lm.Node.World * S);
            var seen = new List<Target>();
            for (int i = 0; i < Joints.LevelNames.Length; i++)
            {
                LevelNode joint;
                if (lm.Joints.TryGetValue(Joints.LevelNames[i], out joint))
                    seen.Add(new Target(Joints.Fingertips[i], levelToWorld.Point(joint.World.T)));
            }
            placed.SeenFingertips = seen.ToArray();
            placed.HandStart = levelToWorld.Point(lm.HandStartM);
            placed.VirtualTarget = levelToWorld.Point(lm.VirtualTargetM);
            placed.PhysicalTarget = (P * S * propNode.World.Inverse).Point(lm.PhysicalTargetM);
            return placed;
        }

        /// <summary>The prop's side of a choice: fingertip pads, centre and approach, the prop's
        /// file frame (mm) mapped to Unity's world by <paramref name="toWorld"/>.</summary>
        static Placed Fingers(MatchesFile file, Choice choice, Affine toWorld)
        {
            var grasp = choice.OnTangible;
            var pads = grasp.PadsMm(file.FingertipRadiusMm);
            var tips = new Target[pads.Length];
            for (int i = 0; i < pads.Length; i++) tips[i] = new Target(Joints.Fingertips[i], toWorld.Point(pads[i]));
            return new Placed
            {
                Tangible = choice.Tangible,
                Cost = choice.Cost,
                Fingertips = tips,
                PinchCenter = toWorld.Point(grasp.CenterMm),
                Approach = grasp.Approach.HasValue
                    ? toWorld.Direction(grasp.Approach.Value).Normalized : (Vec3?)null,
            };
        }

        /// <summary>Where the wrist goes: WristMm from the pinch's centre along the approach (null
        /// without an approach).</summary>
        public static Vec3? Wrist(Placed placed)
        {
            if (!placed.Approach.HasValue) return null;
            return placed.PinchCenter + placed.Approach.Value * (Joints.WristMm / 1000.0);
        }
    }
}
