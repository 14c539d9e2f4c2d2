// The carousel of --placement fixed: the objects it brings onto a prop, in the page's order, the
// ring they wait on (xr_core.js: carouselQueue, carouselRing) and which one is on the prop.
using System;
using System.Collections.Generic;

namespace Pinchmatch
{
    public sealed class Carousel
    {
        /// <summary>The matches (indices into file.Matches) the carousel serves on the prop
        /// <paramref name="prop"/> (every prop: null), in the result's order.</summary>
        public static List<int> Queue(MatchesFile file, string prop)
        {
            var queue = new List<int>();
            for (int i = 0; i < file.Matches.Count; i++)
            {
                var m = file.Matches[i];
                if (m.Redirection != null && m.Redirection.Mode == "carousel" && m.Best != null
                    && (prop == null || m.Best.Tangible == prop))
                    queue.Add(i);
            }
            return queue;
        }

        /// <summary>The ring: objects of footprint radii r (m) side by side around it, each its share
        /// of the turn in proportion to 2 r + gap; the least radius (never below <paramref
        /// name="least"/>) at which every two neighbours' middles are at least r_i + r_j + gap apart
        /// (the chord). Angles (rad): the footprints' middles, the first at 0.</summary>
        public static double Ring(double[] radii, double least, double gap, out double[] angles)
        {
            int n = radii.Length;
            var arcs = new double[n];
            double total = 0;
            for (int i = 0; i < n; i++) { arcs[i] = 2 * radii[i] + gap; total += arcs[i]; }
            if (total == 0) total = 1;
            var step = new double[n];
            for (int i = 0; i < n; i++) step[i] = Math.PI * (arcs[i] + arcs[(i + 1) % n]) / total;
            double radius = least;
            for (int i = 0; i < n && n > 1; i++)
            {
                double need = radii[i] + radii[(i + 1) % n] + gap;
                radius = Math.Max(radius, need / (2 * Math.Sin(Math.Min(step[i], Math.PI) / 2)));
            }
            double largest = 0;
            foreach (var r in radii) largest = Math.Max(largest, r);
            radius = Math.Max(radius, n > 0 ? largest + gap : 0);
            angles = new double[n];
            for (int i = 1; i < n; i++) angles[i] = angles[i - 1] + step[i - 1];
            return radius;
        }

        readonly List<int> queue;
        int at = -1;

        public Carousel(MatchesFile file, string prop) { queue = Queue(file, prop); }

        /// <summary>The match on the prop (an index into the result's matches), -1 before the first
        /// turn or for an empty carousel.</summary>
        public int OnProp { get { return at < 0 || queue.Count == 0 ? -1 : queue[at]; } }

        public int Count { get { return queue.Count; } }

        /// <summary>One turn: the next object comes onto the prop, the one there goes back.</summary>
        public int Turn()
        {
            if (queue.Count == 0) return -1;
            at = (at + 1) % queue.Count;
            return queue[at];
        }

        /// <summary>Turns until the match <paramref name="index"/> is on the prop (how many turns; -1
        /// where the carousel does not serve it).</summary>
        public int BringOn(int index)
        {
            if (!queue.Contains(index)) return -1;
            int turns = 0;
            while (OnProp != index) { Turn(); turns++; }
            return turns;
        }
    }
}
