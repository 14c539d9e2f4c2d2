// The hand's warp under --placement fixed: body warping after Azmandian et al. 2016, exactly the rule
// of the page's headset mode (xr_core.js: warpRatio, warpOffset; scene_xr.js: the grasp's middle).
// It holds in any frame that preserves distances, Unity's included.
using System;

namespace Pinchmatch
{
    public static class Warp
    {
        /// <summary>How far the hand h has come from the warp's origin w0 toward the physical target
        /// wT, projected on the line between them and clamped to [0, 1]: 0 at the start (and behind
        /// it), 1 at the target.</summary>
        public static double Ratio(Vec3 w0, Vec3 wT, Vec3 h)
        {
            var path = wT - w0;
            double length2 = Vec3.Dot(path, path);
            if (!(length2 > 0)) return 1;
            return Math.Max(0, Math.Min(1, Vec3.Dot(path, h - w0) / length2));
        }

        /// <summary>The seen hand's offset from the real one at h: the ratio times (virtual -
        /// physical target), so that the seen fingers reach the virtual grasp exactly when the real
        /// ones reach the prop.</summary>
        public static Vec3 Offset(Vec3 w0, Vec3 physical, Vec3 virtualTarget, Vec3 h)
        {
            return (virtualTarget - physical) * Ratio(w0, physical, h);
        }

        /// <summary>The seen fingertips: each real one moved by the offset at the fingertips' middle
        /// (a pinch's midpoint, a tripod's centroid).</summary>
        public static Vec3[] Fingertips(Vec3 start, Vec3 physical, Vec3 virtualTarget, Vec3[] real)
        {
            var d = Offset(start, physical, virtualTarget, Vec3.Centroid(real));
            var seen = new Vec3[real.Length];
            for (int i = 0; i < real.Length; i++) seen[i] = real[i] + d;
            return seen;
        }

        /// <summary>The seen fingertips of a placed choice (unchanged unless it is redirected).</summary>
        public static Vec3[] Fingertips(Placed placed, Vec3[] real)
        {
            if (!placed.Warped) return (Vec3[])real.Clone();
            return Fingertips(placed.HandStart, placed.PhysicalTarget, placed.VirtualTarget, real);
        }
    }
}
