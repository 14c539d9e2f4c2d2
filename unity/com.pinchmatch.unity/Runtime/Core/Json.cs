// A small JSON reader and writer for pinchmatch's files (RFC 8259), with numbers read as double.
// Objects become Dictionary<string, object>, arrays List<object>, strings string, numbers double,
// true/false bool and null null. Engine-free: it runs in the Unity player and under Mono alike.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.Text;

namespace Pinchmatch
{
    /// <summary>Thrown for text that is not JSON, with the offset where reading stopped.</summary>
    public sealed class JsonException : Exception
    {
        public JsonException(string message) : base(message) { }
    }

    /// <summary>Reads and writes JSON text.</summary>
    public static class Json
    {
        /// <summary>The value the text holds; a JsonException names what is wrong and where.</summary>
        public static object Parse(string text)
        {
            if (text == null) throw new JsonException("no JSON text (null)");
            var reader = new Reader(text);
            reader.SkipSpace();
            object value = reader.Value(0);
            reader.SkipSpace();
            if (!reader.AtEnd) throw reader.Error("text after the JSON value");
            return value;
        }

        /// <summary>The value as compact JSON: numbers in the shortest form that reads back the same
        /// double ("R"), object keys in the dictionary's order.</summary>
        public static string Write(object value)
        {
            var sb = new StringBuilder();
            WriteValue(sb, value);
            return sb.ToString();
        }

        static void WriteValue(StringBuilder sb, object value)
        {
            if (value == null) { sb.Append("null"); return; }
            if (value is bool) { sb.Append((bool)value ? "true" : "false"); return; }
            if (value is string) { WriteString(sb, (string)value); return; }
            if (value is double || value is float || value is int || value is long)
            {
                double d = Convert.ToDouble(value, CultureInfo.InvariantCulture);
                if (double.IsNaN(d) || double.IsInfinity(d)) { sb.Append("null"); return; }
                sb.Append(d.ToString("R", CultureInfo.InvariantCulture));
                return;
            }
            var dict = value as IDictionary<string, object>;
            if (dict != null)
            {
                sb.Append('{');
                bool first = true;
                foreach (var pair in dict)
                {
                    if (!first) sb.Append(',');
                    first = false;
                    WriteString(sb, pair.Key);
                    sb.Append(':');
                    WriteValue(sb, pair.Value);
                }
                sb.Append('}');
                return;
            }
            var list = value as System.Collections.IEnumerable;
            if (list != null)
            {
                sb.Append('[');
                bool first = true;
                foreach (var item in list)
                {
                    if (!first) sb.Append(',');
                    first = false;
                    WriteValue(sb, item);
                }
                sb.Append(']');
                return;
            }
            throw new ArgumentException("cannot write a " + value.GetType().Name + " as JSON");
        }

        static void WriteString(StringBuilder sb, string s)
        {
            sb.Append('"');
            foreach (char c in s)
            {
                switch (c)
                {
                    case '"': sb.Append("\\\""); break;
                    case '\\': sb.Append("\\\\"); break;
                    case '\n': sb.Append("\\n"); break;
                    case '\r': sb.Append("\\r"); break;
                    case '\t': sb.Append("\\t"); break;
                    default:
                        if (c < 0x20) sb.Append("\\u").Append(((int)c).ToString("x4"));
                        else sb.Append(c);
                        break;
                }
            }
            sb.Append('"');
        }

        const int MaxDepth = 512;

        sealed class Reader
        {
            readonly string text;
            int at;

            public Reader(string text) { this.text = text; }

            public bool AtEnd { get { return at >= text.Length; } }

            public JsonException Error(string what)
            {
                return new JsonException(what + " at character " + at);
            }

            public void SkipSpace()
            {
                while (at < text.Length && (text[at] == ' ' || text[at] == '\t' || text[at] == '\n'
                                            || text[at] == '\r'))
                    at++;
            }

            public object Value(int depth)
            {
                if (depth > MaxDepth) throw Error("JSON nested deeper than " + MaxDepth);
                if (AtEnd) throw Error("unexpected end of the text");
                char c = text[at];
                switch (c)
                {
                    case '{': return Obj(depth);
                    case '[': return Arr(depth);
                    case '"': return Str();
                    case 't': Word("true"); return true;
                    case 'f': Word("false"); return false;
                    case 'n': Word("null"); return null;
                    default:
                        if (c == '-' || (c >= '0' && c <= '9')) return Number();
                        throw Error("unexpected character '" + c + "'");
                }
            }

            void Word(string word)
            {
                if (string.CompareOrdinal(text, at, word, 0, word.Length) != 0)
                    throw Error("expected '" + word + "'");
                at += word.Length;
            }

            Dictionary<string, object> Obj(int depth)
            {
                var d = new Dictionary<string, object>();
                at++;
                SkipSpace();
                if (!AtEnd && text[at] == '}') { at++; return d; }
                while (true)
                {
                    SkipSpace();
                    if (AtEnd || text[at] != '"') throw Error("expected a key");
                    string key = Str();
                    SkipSpace();
                    if (AtEnd || text[at] != ':') throw Error("expected ':'");
                    at++;
                    SkipSpace();
                    d[key] = Value(depth + 1);
                    SkipSpace();
                    if (AtEnd) throw Error("unclosed object");
                    if (text[at] == ',') { at++; continue; }
                    if (text[at] == '}') { at++; return d; }
                    throw Error("expected ',' or '}'");
                }
            }

            List<object> Arr(int depth)
            {
                var list = new List<object>();
                at++;
                SkipSpace();
                if (!AtEnd && text[at] == ']') { at++; return list; }
                while (true)
                {
                    SkipSpace();
                    list.Add(Value(depth + 1));
                    SkipSpace();
                    if (AtEnd) throw Error("unclosed array");
                    if (text[at] == ',') { at++; continue; }
                    if (text[at] == ']') { at++; return list; }
                    throw Error("expected ',' or ']'");
                }
            }

            string Str()
            {
                at++;
                var sb = new StringBuilder();
                while (true)
                {
                    if (AtEnd) throw Error("unclosed string");
                    char c = text[at++];
                    if (c == '"') return sb.ToString();
                    if (c < 0x20) throw Error("a control character in a string");
                    if (c != '\\') { sb.Append(c); continue; }
                    if (AtEnd) throw Error("unclosed string");
                    char e = text[at++];
                    switch (e)
                    {
                        case '"': sb.Append('"'); break;
                        case '\\': sb.Append('\\'); break;
                        case '/': sb.Append('/'); break;
                        case 'b': sb.Append('\b'); break;
                        case 'f': sb.Append('\f'); break;
                        case 'n': sb.Append('\n'); break;
                        case 'r': sb.Append('\r'); break;
                        case 't': sb.Append('\t'); break;
                        case 'u':
                            if (at + 4 > text.Length) throw Error("a short \\u escape");
                            int code;
                            if (!int.TryParse(text.Substring(at, 4), NumberStyles.HexNumber,
                                              CultureInfo.InvariantCulture, out code))
                                throw Error("a bad \\u escape");
                            sb.Append((char)code);
                            at += 4;
                            break;
                        default: throw Error("a bad escape '\\" + e + "'");
                    }
                }
            }

            double Number()
            {
                int start = at;
                if (text[at] == '-') at++;
                if (AtEnd || !char.IsDigit(text[at])) throw Error("a number without digits");
                if (text[at] == '0') at++;
                else while (!AtEnd && char.IsDigit(text[at])) at++;
                if (!AtEnd && text[at] == '.')
                {
                    at++;
                    if (AtEnd || !char.IsDigit(text[at])) throw Error("no digits after '.'");
                    while (!AtEnd && char.IsDigit(text[at])) at++;
                }
                if (!AtEnd && (text[at] == 'e' || text[at] == 'E'))
                {
                    at++;
                    if (!AtEnd && (text[at] == '+' || text[at] == '-')) at++;
                    if (AtEnd || !char.IsDigit(text[at])) throw Error("no digits in the exponent");
                    while (!AtEnd && char.IsDigit(text[at])) at++;
                }
                return double.Parse(text.Substring(start, at - start), NumberStyles.Float,
                                    CultureInfo.InvariantCulture);
            }
        }
    }

    /// <summary>Typed reads of parsed JSON, each naming the field that is missing or wrong.</summary>
    public static class JsonFields
    {
        public static Dictionary<string, object> Obj(object value, string what)
        {
            var d = value as Dictionary<string, object>;
            if (d == null) throw new JsonException(what + " is not a JSON object");
            return d;
        }

        public static List<object> Arr(object value, string what)
        {
            var a = value as List<object>;
            if (a == null) throw new JsonException(what + " is not a JSON array");
            return a;
        }

        public static object Get(Dictionary<string, object> d, string key, string what)
        {
            object v;
            if (!d.TryGetValue(key, out v)) throw new JsonException(what + " has no '" + key + "'");
            return v;
        }

        public static object Opt(Dictionary<string, object> d, string key)
        {
            object v;
            return d.TryGetValue(key, out v) ? v : null;
        }

        public static double Num(object value, string what)
        {
            if (!(value is double)) throw new JsonException(what + " is not a number");
            return (double)value;
        }

        public static string Str(object value, string what)
        {
            var s = value as string;
            if (s == null) throw new JsonException(what + " is not a string");
            return s;
        }

        public static double[] Nums(object value, string what, int count)
        {
            var a = Arr(value, what);
            if (count >= 0 && a.Count != count)
                throw new JsonException(what + " has " + a.Count + " numbers, not " + count);
            var out_ = new double[a.Count];
            for (int i = 0; i < a.Count; i++) out_[i] = Num(a[i], what + "[" + i + "]");
            return out_;
        }

        public static Vec3 Vec(object value, string what)
        {
            var n = Nums(value, what, 3);
            return new Vec3(n[0], n[1], n[2]);
        }
    }
}
